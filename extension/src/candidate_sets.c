/*
 * The snippets a call may choose among when it names a transition graph or a collection, as sorted ids,
 * so that a candidate outside them is passed over when its block is read instead of when its row is (a
 * start in a graph of half the data read thousands of rows only to have the graph refuse them; a call in
 * a small collection reads the rows of other collections' candidates likewise).
 *
 * A call reads them once it has refused rows (selection.c's read_members; a start its graph's at once),
 * under its snapshot, and the session keeps them by what they depend on: a graph's members by
 * its id and both generations (a graph is rebuilt under a new modb.graphs row, which takes a new plans
 * generation; its rows of deleted snippets go with the blocks', which take a new blocks generation), a
 * collection's by its ids (a move of a collection changes its subtree) and the blocks generation (every
 * insert, delete or change of a snippet's collection changes blocks). Generations are never reused, so a
 * set is right for every snapshot that sees its numbers. A set larger than MAX_MEMBERS, or a collection
 * of more than a quarter of the snippets, is not kept (it would filter little and cost a session's first
 * call much): NULL, and the rows' filters decide alone.
 */
#include "postgres.h"

#include "catalog/pg_type.h"
#include "utils/array.h"
#include "utils/memutils.h"

#include "kept_plans.h"
#include "selection.h"

#define MAX_MEMBERS 65536
#define MIN_LIMIT 4096			/* a collection's: at least this many, else a quarter of the snippets */
#define KEPT_SETS 4

typedef struct MemberSet
{
	bool		used;
	bool		graph;			/* else a collection's */
	int64		graph_id;
	int64		plans_generation;
	int64		blocks_generation;
	int64	   *collections;	/* sorted */
	int			n_collections;
	int64	   *ids;			/* sorted; NULL: more than MAX_MEMBERS */
	int			n;
	uint64		last_used;
} MemberSet;

static MemberSet kept[KEPT_SETS];
static uint64 uses;

static int
int64_order(const void *a, const void *b)
{
	int64		x = *(const int64 *) a,
				y = *(const int64 *) b;

	return x < y ? -1 : (x > y ? 1 : 0);
}

/* The kept set to reuse for this key, or the one to replace (emptied). */
static MemberSet *
slot_for(bool graph, int64 graph_id, int64 plans_generation, int64 blocks_generation, const int64 *collections,
		 int n_collections, bool *found)
{
	MemberSet  *oldest = &kept[0];

	for (int i = 0; i < KEPT_SETS; i++)
	{
		MemberSet  *s = &kept[i];

		if (s->used && s->graph == graph && s->blocks_generation == blocks_generation
			&& (graph ? s->graph_id == graph_id && s->plans_generation == plans_generation
				: s->n_collections == n_collections
				&& memcmp(s->collections, collections, sizeof(int64) * n_collections) == 0))
		{
			*found = true;
			s->last_used = ++uses;
			return s;
		}
		if (!s->used || (oldest->used && s->last_used < oldest->last_used))
			oldest = s;
	}
	*found = false;
	if (oldest->used)
	{
		if (oldest->ids)
			pfree(oldest->ids);
		if (oldest->collections)
			pfree(oldest->collections);
	}
	memset(oldest, 0, sizeof(MemberSet));
	return oldest;
}

/* Runs query ($1) for the sorted ids (int8[]) and whether they are all (bool) into s (n -1: too many). */
static void
read_members(MemberSet *s, SPIPlanPtr query, Datum first)
{
	Datum		args[1] = {first};
	bool		isnull;
	Datum		value;
	ArrayType  *a;
	int			n;

	if (SPI_execute_plan(query, args, NULL, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
		elog(ERROR, "modb: reading the snippets of a graph or collection failed");
	if (!DatumGetBool(SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 2, &isnull)))
	{
		s->n = -1;
		return;
	}
	value = SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 1, &isnull);
	if (isnull)
		return;					/* none: an empty set */
	a = DatumGetArrayTypeP(value);
	n = ArrayGetNItems(ARR_NDIM(a), ARR_DIMS(a));
	s->ids = MemoryContextAlloc(TopMemoryContext, sizeof(int64) * Max(n, 1));
	memcpy(s->ids, ARR_DATA_PTR(a), sizeof(int64) * n);
	s->n = n;
}

const MemberSet *
modb_graph_members(int64 graph_id, int64 plans_generation, int64 blocks_generation)
{
	static SPIPlanPtr query;
	Oid			types[1] = {INT8OID};
	bool		found;
	MemberSet  *s = slot_for(true, graph_id, plans_generation, blocks_generation, NULL, 0, &found);

	if (found)
		return s->n < 0 ? NULL : s;
	modb_kept_plan(&query,
				   "SELECT array_agg(g.snippet_id ORDER BY g.snippet_id), count(*) <= " CppAsString2(MAX_MEMBERS)
				   "  FROM (SELECT g.snippet_id FROM modb.graph_snippets g WHERE g.graph_id = $1"
				   "         LIMIT " CppAsString2(MAX_MEMBERS) " + 1) g",
				   1, types);
	read_members(s, query, Int64GetDatum(graph_id));
	s->graph = true;
	s->graph_id = graph_id;
	s->plans_generation = plans_generation;
	s->blocks_generation = blocks_generation;
	s->used = true;
	s->last_used = ++uses;
	return s->n < 0 ? NULL : s;
}

const MemberSet *
modb_collection_members(const int64 *collections, int n_collections, int64 blocks_generation)
{
	static SPIPlanPtr query;
	Oid			types[1] = {INT8ARRAYOID};
	int64	   *sorted = palloc(sizeof(int64) * Max(n_collections, 1));
	Datum	   *elements = palloc(sizeof(Datum) * Max(n_collections, 1));
	bool		found;
	MemberSet  *s;

	memcpy(sorted, collections, sizeof(int64) * n_collections);
	qsort(sorted, n_collections, sizeof(int64), int64_order);
	s = slot_for(false, 0, 0, blocks_generation, sorted, n_collections, &found);
	if (found)
		return s->n < 0 ? NULL : s;
	for (int i = 0; i < n_collections; i++)
		elements[i] = Int64GetDatum(sorted[i]);
	modb_kept_plan(&query,
				   "WITH l AS (SELECT greatest(" CppAsString2(MIN_LIMIT) ", least(" CppAsString2(MAX_MEMBERS) ","
				   "                    (SELECT c.reltuples / 4 FROM pg_catalog.pg_class c"
				   "                      WHERE c.oid = 'modb.snippets'::regclass)))::int AS n)"
				   "SELECT array_agg(s.id ORDER BY s.id), count(*) <= (SELECT n FROM l)"
				   "  FROM (SELECT s.id FROM modb.snippets s WHERE s.collection_id = ANY ($1)"
				   "         LIMIT (SELECT n + 1 FROM l)) s",
				   1, types);
	read_members(s, query,
				 PointerGetDatum(construct_array(elements, n_collections, INT8OID, 8, FLOAT8PASSBYVAL,
												 TYPALIGN_DOUBLE)));
	s->collections = MemoryContextAlloc(TopMemoryContext, sizeof(int64) * Max(n_collections, 1));
	memcpy(s->collections, sorted, sizeof(int64) * n_collections);
	s->n_collections = n_collections;
	s->blocks_generation = blocks_generation;
	s->used = true;
	s->last_used = ++uses;
	return s->n < 0 ? NULL : s;
}

bool
modb_members_hold(const MemberSet *s, int64 id)
{
	return bsearch(&id, s->ids, s->n, sizeof(int64), int64_order) != NULL;
}
