/*
 * select_next_snippets in C: the rule of select_next_snippets_reference (86_selection.sql), computed without
 * planning a query per call. The plan is resolved once per session (selection_plan.c); the previous
 * snippet's end, the box of each relaxation level (GiST) or the graph's stored transitions, and the
 * candidates' begin terminators are read by kept generic SPI plans under the caller's snapshot; the
 * filters, the continuity ratio (continuity.c), the objective (objective.c) and the order are computed
 * here, level by level, stopping once k rows are found. What the fast path does not compute is answered by
 * the reference query itself (a start without a previous snippet, level 4 - the nearest start at any
 * ratio -, graph_lookahead), so every answer is the reference's (tests/test_select_fast.py).
 */
#include "postgres.h"

#include <math.h>

#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "funcapi.h"
#include "lib/binaryheap.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/guc.h"
#include "utils/hsearch.h"

#include "extension/cube/cubedata.h"
#include "selection.h"
#include "term_codes.h"

PG_FUNCTION_INFO_V1(modb_select_next_snippets);
PG_FUNCTION_INFO_V1(modb_select_snippet_ending);

/* The columns both candidate queries start with. */
#define CANDIDATE_COLUMNS \
	"c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames, c.collection_id, c.pose_key, c.fps," \
	" c.net_translation, c.net_rotation, c.net_heading, c.future_translation, c.future_heading," \
	" b.positions, b.rotations, b.velocities, b.angular_velocities, c.begin_features"
enum
{
	COL_ID = 1, COL_CLIP, COL_VERSION, COL_MIRRORED, COL_FIRST_FRAME, COL_N_FRAMES, COL_COLLECTION,
	COL_POSE_KEY, COL_FPS, COL_NET_TRANSLATION, COL_NET_ROTATION, COL_NET_HEADING, COL_FUTURE_TRANSLATION,
	COL_FUTURE_HEADING, COL_POSITIONS, COL_ROTATIONS, COL_VELOCITIES, COL_ANGULAR_VELOCITIES,
	COL_BEGIN_FEATURES, COL_COST_TO_GO
};

/* Candidates one query reads, at first; each next query reads twice as many. */
#define FIRST_BATCH 16
#define LARGEST_BATCH 512

/* A stretch of frames a clip source played: the frames after a snippet's first (its seam). */
typedef struct Played
{
	int64		clip_id;
	int32		version;
	bool		mirrored;
	int32		low;
	int32		high;
} Played;

typedef struct Request
{
	int64		prev;
	double		target[3];
	int			n;				/* 2: {x, z}; 3: {x, y, z} */
	double		aim[3];
	double		direction;		/* of the aim point (modb_aim_direction) */
	int			k;
	const MatchPlan *plan;
	/* the previous snippet's end */
	Terminator	end;
	double		features[N_FEATURES];
	char	   *pose_key;
	double		fps;
	/* which blocks this snapshot sees (block_directory.c) */
	Oid			blocks_relid;
	int64		blocks_generation;
	int64		plans_generation;	/* of the profiles and graphs (selection_plan.c) */
	const char *extension_version;	/* with blocks_relid, what a plan shared between sessions is valid for */
	/* filters */
	Played	   *played;
	int			n_played;
	int64	   *collections;	/* NULL: every collection */
	int			n_collections;
	/*
	 * The snippets of the graph its rows are restricted to (graph_rows) and of the collection, once rows
	 * read have been refused for being outside them (candidate_sets.c; NULL: not known, rows decide).
	 */
	bool		graph_rows;
	int			refused;
	bool		members_read;
	const MemberSet *graph_members;
	const MemberSet *collection_members;
} Request;

/* Rows a call may have refused (graph, filters) before it reads who is inside the graph and collection. */
#define REFUSED_BEFORE_MEMBERS 64

/* A candidate row, deformed once (SPI_getbinval walks the tuple from its start at every call). */
typedef struct Row
{
	Datum		values[COL_COST_TO_GO];
	bool		nulls[COL_COST_TO_GO];
} Row;

static inline Datum
row_value(const Row *row, int column, bool *isnull)
{
	*isnull = row->nulls[column - 1];
	return row->values[column - 1];
}

/* A candidate read and checked. */
typedef struct Candidate
{
	const Row  *row;
	int64		id;
	bool		has_key;
	double		key;			/* objective + continuity_weight x ratio */
	bool		has_proximity;
	double		proximity;
	double		ratio;
} Candidate;

/*
 * A candidate not read yet, or a block not read yet: the least key it can have, from the objective inputs
 * its block holds (a block: from their bounds over its snippets).
 */
typedef struct Pending
{
	int64		id;				/* a block's: PG_INT64_MIN, first among equal bounds */
	int			block;			/* the box search's block, or -1: a candidate */
	bool		hinted;			/* false: unknown (read first) */
	bool		has_proximity;
	double		bound;
	double		least_ratio;	/* from its block's term codes (0: unknown) */
} Pending;

static const float *
float4_array(Datum value, int length)
{
	ArrayType  *a = DatumGetArrayTypeP(value);

	if (ARR_NDIM(a) != 1 || ARR_HASNULL(a) || ARR_DIMS(a)[0] != length)
		elog(ERROR, "modb: a terminator array is not %d values", length);
	return (const float *) ARR_DATA_PTR(a);
}

/* A float8[] column's values (NULL when the column is); *n gets its length. */
static const double *
float8_array(Datum value, bool isnull, int *n)
{
	ArrayType  *a;

	if (isnull)
		return NULL;
	a = DatumGetArrayTypeP(value);
	if (ARR_NDIM(a) != 1 || ARR_HASNULL(a))
		return NULL;
	*n = ARR_DIMS(a)[0];
	return (const double *) ARR_DATA_PTR(a);
}

/* A terminator from four consecutive array values (positions, rotations, velocities, angular ones). */
static Terminator
terminator_of(const Datum *values)
{
	Terminator	t;

	t.positions = float4_array(values[0], 3 * N_JOINTS);
	t.rotations = float4_array(values[1], 4 * N_JOINTS);
	t.velocities = float4_array(values[2], 3 * N_JOINTS);
	t.angular_velocities = float4_array(values[3], 3 * N_JOINTS);
	return t;
}

/* The cheap part of modb.check_request; what fails it goes to check_request itself for its error. */
static bool
target_ok(ArrayType *target, Request *r)
{
	if (ARR_NDIM(target) != 1 || ARR_HASNULL(target) || ARR_LBOUND(target)[0] != 1
		|| (ARR_DIMS(target)[0] != 2 && ARR_DIMS(target)[0] != 3))
		return false;
	r->n = ARR_DIMS(target)[0];
	for (int i = 0; i < r->n; i++)
	{
		r->target[i] = ((double *) ARR_DATA_PTR(target))[i];
		if (!(fabs(r->target[i]) <= 1e9))
			return false;
	}
	return true;
}

/*
 * Raises the request's error, if it has one, as the reference would: modb.match_plan (the profile) first,
 * then modb.check_request (target, k, prev, collection); and reads the collection's subtree.
 */
static void
check_request(FunctionCallInfo fcinfo, int64 **collections, int *n_collections)
{
	static SPIPlanPtr query;
	static const int arg_of[5] = {0, 1, 2, 4, 3};	/* prev, target, k, collection, profile */
	Oid			types[5] = {INT8OID, FLOAT8ARRAYOID, INT4OID, TEXTOID, TEXTOID};
	Datum		args[5];
	char		nulls[5];
	bool		isnull;
	Datum		ids;

	for (int i = 0; i < 5; i++)
	{
		nulls[i] = PG_ARGISNULL(arg_of[i]) ? 'n' : ' ';
		args[i] = nulls[i] == 'n' ? (Datum) 0 : PG_GETARG_DATUM(arg_of[i]);
	}
	modb_kept_plan(&query,
				   "SELECT modb.match_plan($5) IS NOT NULL, modb.check_request($1, $2, $3, $4),"
				   "       CASE WHEN $4 IS NOT NULL THEN modb.collection_subtree($4) END",
				   5, types);
	if (SPI_execute_plan(query, args, nulls, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
		elog(ERROR, "modb: check_request returned nothing");
	ids = SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 3, &isnull);
	if (!isnull && collections != NULL)
	{
		ArrayType  *a = DatumGetArrayTypeP(ids);
		Datum	   *elements;
		bool	   *element_nulls;

		deconstruct_array(a, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE, &elements, &element_nulls,
						  n_collections);
		*collections = palloc(sizeof(int64) * Max(*n_collections, 1));
		for (int i = 0; i < *n_collections; i++)
			(*collections)[i] = element_nulls[i] ? -1 : DatumGetInt64(elements[i]);
	}
}

/* The frames a snippet row (clip_id, version, mirrored, first_frame, n_frames, in that order) played. */
static Played
played_of(HeapTuple row, TupleDesc desc)
{
	bool		isnull;
	Played		p;

	p.clip_id = DatumGetInt64(SPI_getbinval(row, desc, 1, &isnull));
	p.version = DatumGetInt32(SPI_getbinval(row, desc, 2, &isnull));
	p.mirrored = DatumGetBool(SPI_getbinval(row, desc, 3, &isnull));
	p.low = DatumGetInt32(SPI_getbinval(row, desc, 4, &isnull)) + 1;
	p.high = p.low - 2 + DatumGetInt32(SPI_getbinval(row, desc, 5, &isnull));
	return p;
}

/* What every call reads beside its request: the generations, the blocks' relation, the version. */
#define GENERATION_COLUMNS \
	"(SELECT g.generation FROM modb.generations g WHERE g.name = 'snippet_blocks')," \
	" to_regclass('modb.snippet_blocks')::oid," \
	" (SELECT g.generation FROM modb.generations g WHERE g.name = 'match_plans')," \
	" (SELECT x.extversion FROM pg_catalog.pg_extension x WHERE x.extname = 'modb')"

/* GENERATION_COLUMNS, from column `first` of a row. */
static void
generations_of(Request *r, HeapTuple row, TupleDesc desc, int first)
{
	bool		isnull;

	r->blocks_generation = DatumGetInt64(SPI_getbinval(row, desc, first, &isnull));
	r->blocks_relid = DatumGetObjectId(SPI_getbinval(row, desc, first + 1, &isnull));
	r->plans_generation = DatumGetInt64(SPI_getbinval(row, desc, first + 2, &isnull));
	r->extension_version = SPI_getvalue(row, desc, first + 3);
}

/* The previous snippet's end terminator and the frames it played; false when there is no such snippet. */
static bool
read_previous(Request *r)
{
	static SPIPlanPtr query;
	Oid			types[1] = {INT8OID};
	Datum		args[1] = {Int64GetDatum(r->prev)};
	HeapTuple	row;
	TupleDesc	desc;
	bool		isnull;
	NDBOX	   *features;

	modb_kept_plan(&query,
				   "SELECT s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, s.pose_key, s.fps, t.features,"
				   "       t.positions, t.rotations, t.velocities, t.angular_velocities, " GENERATION_COLUMNS
				   "  FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = $1",
				   1, types);
	if (SPI_execute_plan(query, args, NULL, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
		return false;
	row = SPI_tuptable->vals[0];
	desc = SPI_tuptable->tupdesc;
	r->played = palloc(sizeof(Played));
	r->played[0] = played_of(row, desc);
	r->n_played = 1;
	r->pose_key = SPI_getvalue(row, desc, 6);
	r->fps = DatumGetFloat8(SPI_getbinval(row, desc, 7, &isnull));
	features = DatumGetNDBOXP(SPI_getbinval(row, desc, 8, &isnull));
	if (DIM(features) != N_FEATURES)
		elog(ERROR, "modb: terminator features have %d dimensions, not %d", DIM(features), N_FEATURES);
	for (int i = 0; i < N_FEATURES; i++)
		r->features[i] = LL_COORD(features, i);
	{
		Datum		arrays[4];

		for (int i = 0; i < 4; i++)
			arrays[i] = SPI_getbinval(row, desc, 9 + i, &isnull);
		r->end = terminator_of(arrays);
	}
	generations_of(r, row, desc, 13);
	return true;
}

/* The frames the snippets of `exclude` played (after their first), beside the previous snippet's. */
static void
read_excluded(Request *r, Datum exclude)
{
	static SPIPlanPtr query;
	Oid			types[1] = {INT8ARRAYOID};
	Datum		args[1] = {exclude};

	modb_kept_plan(&query,
				   "SELECT x.clip_id, x.version, x.mirrored, x.first_frame, x.n_frames FROM modb.snippets x"
				   " WHERE x.id = ANY ($1)",
				   1, types);
	if (SPI_execute_plan(query, args, NULL, true, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: reading the excluded snippets failed");
	r->played = r->played ? repalloc(r->played, sizeof(Played) * (r->n_played + SPI_processed))
		: palloc(sizeof(Played) * Max(SPI_processed, 1));
	for (uint64 i = 0; i < SPI_processed; i++)
		r->played[r->n_played++] = played_of(SPI_tuptable->vals[i], SPI_tuptable->tupdesc);
}

/* The candidates CTE of the reference: the collection, and no replay of a played frame. */
static bool
passes_filters(const Request *r, const Row *row)
{
	bool		isnull;
	int64		clip_id = DatumGetInt64(row_value(row, COL_CLIP, &isnull));
	int32		version = DatumGetInt32(row_value(row, COL_VERSION, &isnull));
	bool		mirrored = DatumGetBool(row_value(row, COL_MIRRORED, &isnull));
	int32		low = DatumGetInt32(row_value(row, COL_FIRST_FRAME, &isnull)) + 1;
	int32		high = low - 2 + DatumGetInt32(row_value(row, COL_N_FRAMES, &isnull));

	if (r->collections != NULL)
	{
		int64		collection = DatumGetInt64(row_value(row, COL_COLLECTION, &isnull));
		bool		inside = false;

		for (int i = 0; i < r->n_collections && !inside; i++)
			inside = r->collections[i] == collection;
		if (!inside)
			return false;
	}
	for (int i = 0; i < r->n_played; i++)
	{
		const Played *p = &r->played[i];

		if (p->clip_id == clip_id && p->version == version && p->mirrored == mirrored
			&& Max(p->low, low) <= Min(p->high, high))
			return false;
	}
	return true;
}

static bool
same_pose_and_rate(const Request *r, const Row *row)
{
	bool		isnull;
	double		fps = DatumGetFloat8(row_value(row, COL_FPS, &isnull));
	char	   *pose_key;

	if (fps != r->fps)
		return false;
	pose_key = TextDatumGetCString(row_value(row, COL_POSE_KEY, &isnull));
	return strcmp(pose_key, r->pose_key) == 0;
}

/* modb.approach_cost of a candidate row toward the request's aim point. */
static bool
proximity_of(const Request *r, const Row *row, double *proximity)
{
	int			n_net = 0,
				n_future = 0;
	bool		isnull;
	const double *net = float8_array(row->values[COL_NET_TRANSLATION - 1], row->nulls[COL_NET_TRANSLATION - 1], &n_net);
	const double *future = float8_array(row->values[COL_FUTURE_TRANSLATION - 1], row->nulls[COL_FUTURE_TRANSLATION - 1], &n_future);
	double		future_heading = DatumGetFloat8(row_value(row, COL_FUTURE_HEADING, &isnull));

	return modb_approach_cost(net, n_future == 3 ? future : NULL, !isnull, future_heading, r->aim, r->n, r->direction,
							  r->plan->heading_weight, proximity);
}

/* The graph's objective at level 0: seconds to the goal through the candidate x the graph's speed. */
static bool
graph_objective(const Request *r, const Row *row, double *objective)
{
	int			n_net = 0;
	bool		isnull;
	const double *net = float8_array(row->values[COL_NET_TRANSLATION - 1], row->nulls[COL_NET_TRANSLATION - 1], &n_net);
	double		heading = DatumGetFloat8(row_value(row, COL_NET_HEADING, &isnull));
	int32		n_frames = DatumGetInt32(row_value(row, COL_N_FRAMES, &isnull));
	double		fps = DatumGetFloat8(row_value(row, COL_FPS, &isnull));
	Datum		costs_datum = row_value(row, COL_COST_TO_GO, &isnull);
	const float *costs = NULL;
	int			n_costs = 0;
	double		goal[3];
	double		seconds;

	if (!isnull)
	{
		ArrayType  *a = DatumGetArrayTypeP(costs_datum);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_LBOUND(a)[0] == 1)
		{
			costs = (const float *) ARR_DATA_PTR(a);
			n_costs = ARR_DIMS(a)[0];
		}
	}
	modb_world_to_local(net, heading, r->target, r->n, goal);
	if (!modb_cost_to_go(costs, n_costs, goal, r->n, &r->plan->grid, &seconds))
		return false;
	*objective = r->plan->grid.speed * ((double) (n_frames - 1) / fps + seconds);
	return true;
}

/* A copy that outlives SPI_finish (for explain_selection's report). */
static char *
outliving(const char *text)
{
	char	   *copy = SPI_palloc(strlen(text) + 1);

	strcpy(copy, text);
	return copy;
}

static int
candidate_order(const void *a, const void *b)
{
	const Candidate *x = a,
			   *y = b;

	if (x->has_key != y->has_key)
		return x->has_key ? -1 : 1;		/* NULLs last */
	if (x->has_key && x->key != y->key)
		return x->key < y->key ? -1 : 1;
	return x->id < y->id ? -1 : (x->id > y->id ? 1 : 0);
}


/* cube's <@ of a point in a box: every coordinate within the box's bounds. */
static bool
in_box(const Row *row, const double *lo, const double *hi)
{
	bool		isnull;
	NDBOX	   *features = DatumGetNDBOXP(row_value(row, COL_BEGIN_FEATURES, &isnull));

	if (DIM(features) != N_FEATURES)
		return false;
	for (int d = 0; d < N_FEATURES; d++)
		if (Min(LL_COORD(features, d), UR_COORD(features, d)) < lo[d]
			|| Max(LL_COORD(features, d), UR_COORD(features, d)) > hi[d])
			return false;
	return true;
}

/*
 * In the order candidates are read: unknown ones first, then by the least key they can have, NULLs last.
 */
static int
pending_order(const void *a, const void *b)
{
	const Pending *x = a,
			   *y = b;

	if (x->hinted != y->hinted)
		return x->hinted ? 1 : -1;
	if (x->has_proximity != y->has_proximity)
		return x->has_proximity ? -1 : 1;
	if (x->has_proximity && x->bound != y->bound)
		return x->bound < y->bound ? -1 : 1;
	return x->id < y->id ? -1 : (x->id > y->id ? 1 : 0);
}

/* binaryheap keeps the greatest first: the one pending_order puts first. */
static int
pending_heap_order(Datum a, Datum b, void *arg)
{
	return -pending_order(DatumGetPointer(a), DatumGetPointer(b));
}

/* Puts c into best (sorted, at most `need` long, *n of them) if it ranks among the best `need`. */
static void
keep_best(Candidate *best, int *n, int need, const Candidate *c)
{
	int			at = *n;

	while (at > 0 && candidate_order(c, &best[at - 1]) < 0)
		at--;
	if (at >= need)
		return;
	memmove(&best[at + 1], &best[at], sizeof(Candidate) * (Min(*n, need - 1) - at));
	best[at] = *c;
	*n = Min(*n + 1, need);
}

/* Whether p, at best, still ranks before the last of a full list of the best. */
static bool
may_beat(const Pending *p, const Candidate *last)
{
	Candidate	at_best = {.id = p->id, .has_key = p->has_proximity, .key = p->bound};

	return !p->hinted || candidate_order(&at_best, last) <= 0;
}

/*
 * Coming to rest or setting off (select_snippet_ending_reference, 89_synthesis.sql): among the snippets
 * that end standing (or walking), the least ratio level first, then the one whose net translation ends
 * nearest the goal; candidates are excluded by id only (not by the frames they play). Scale 2^L is
 * searched only when the smaller ones found none, and a snippet within ratio 2^(L-1) lies in their box:
 * so every candidate of scale 2^L has level L (0.29.0's rule: the least L with ratio <= 2^L), and they
 * rank by their distance from the goal alone.
 */
typedef struct Ending
{
	double		target[2];		/* check_world_request's first two values, as the reference reads them */
	bool		standing;
	double		rest_speed;
	double		walk_speed;
	const int64 *exclude;
	int			n_exclude;
} Ending;

/* A level's reading: its query, what the rows must pass, and the best found so far. */
typedef struct LevelRead
{
	Request    *r;				/* not const: it learns the graph's and collection's members */
	const Ending *ending;		/* NULL: select_next_snippets' rule */
	bool		start;			/* no previous snippet: every pose, ranked by the objective alone */
	SPIPlanPtr	query;
	Datum		graph_id;
	bool		no_graph;
	Datum		annotations;	/* the plan's, a text[] literal ($3); unused when it has none */
	const double *lo;			/* the box; NULL for stored transitions */
	const double *hi;
	double		low;			/* low < ratio <= high */
	double		high;
	int			need;
	Candidate  *best;
	int			n_best;
	LevelStats *stats;
} LevelRead;

/* The reference's filters for coming to rest or setting off: collection, exclude (by id) and end speed. */
static bool
ending_filters(const Request *r, const Ending *e, const Row *row)
{
	bool		isnull;
	int64		id = DatumGetInt64(row_value(row, COL_ID, &isnull));
	Datum		speed = row_value(row, COL_COST_TO_GO, &isnull);

	if (r->collections != NULL)
	{
		int64		collection = DatumGetInt64(row_value(row, COL_COLLECTION, &isnull));
		bool		inside = false;

		for (int i = 0; i < r->n_collections && !inside; i++)
			inside = r->collections[i] == collection;
		if (!inside)
			return false;
	}
	for (int i = 0; i < e->n_exclude; i++)
		if (e->exclude[i] == id)
			return false;
	if (row->nulls[COL_COST_TO_GO - 1])
		return false;
	return e->standing ? DatumGetFloat8(speed) < e->rest_speed : DatumGetFloat8(speed) >= e->walk_speed;
}

/*
 * Whether a snippet whose end speed rounds to `speed` as a float4 (NaN: not known) may end as wanted: a
 * float4 is within 2^-24 of its value, allowed for a thousand times over.
 */
static bool
ending_speed_may_pass(float speed, const void *arg)
{
	const Ending *e = arg;
	double		slack = ldexp(fabs((double) speed), -14) + 1e-12;

	if (isnan(speed))
		return true;
	return e->standing ? (double) speed - slack < e->rest_speed : (double) speed + slack >= e->walk_speed;
}

static volatile double two = 2.0;	/* SQL's x ^ 2 is pow(x, 2) */

/* sqrt((net[1] - target[1]) ^ 2 + (net[3] - target[2]) ^ 2), as the reference computes it. */
static bool
ending_proximity(const Ending *e, const Row *row, double *proximity)
{
	int			n_net = 0;
	const double *net = float8_array(row->values[COL_NET_TRANSLATION - 1], row->nulls[COL_NET_TRANSLATION - 1], &n_net);

	if (net == NULL || n_net < 3)
		return false;
	*proximity = sqrt(pow(net[0] - e->target[0], two) + pow(net[2] - e->target[1], two));
	return true;
}

/* The member set of the graph a request's rows are restricted to (kept by the session per generation). */
static void
read_graph_members(Request *r)
{
	if (r->graph_rows && r->plan->has_graph)
		r->graph_members = modb_graph_members(r->plan->graph_id, r->plans_generation, r->blocks_generation);
}

/*
 * The member sets of the graph and collection a request names: read once rows have been refused (most
 * calls that name a large collection, or none, never are), then kept by the session for its generation.
 */
static void
read_members(Request *r)
{
	r->members_read = true;
	read_graph_members(r);
	if (r->collections != NULL)
		r->collection_members = modb_collection_members(r->collections, r->n_collections, r->blocks_generation);
}

/* Reads the rows of ids[0..n) and checks each: the box, pose and rate, filters, ratio, objective. */
static void
read_and_check(LevelRead *lr, const Pending *pending, int n)
{
	Request    *r = lr->r;
	bool		stored = lr->lo == NULL;
	Datum	   *ids = palloc(sizeof(Datum) * n);
	Datum		args[3];
	char		nulls[3] = {' ', lr->no_graph ? 'n' : ' ', r->plan->annotations ? ' ' : 'n'};
	TupleDesc	desc;
	Row		   *rows;

	for (int i = 0; i < n; i++)
		ids[i] = Int64GetDatum(pending[i].id);
	args[0] = PointerGetDatum(construct_array(ids, n, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE));
	args[1] = lr->graph_id;
	args[2] = lr->annotations;
	if (SPI_execute_plan(lr->query, args, nulls, true, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: a selection query failed");
	desc = SPI_tuptable->tupdesc;
	/* Kept to the end of the call: the best rows' values point into them. */
	rows = palloc(sizeof(Row) * Max(SPI_processed, 1));
	if (lr->stats)
		lr->stats->scanned += SPI_processed;
	r->refused += n - SPI_processed;	/* outside the graph (or the annotations) */
	for (uint64 i = 0; i < SPI_processed; i++)
	{
		Row		   *row = &rows[i];
		Candidate	c;
		Terminator	begin;
		bool		isnull;

		heap_deform_tuple(SPI_tuptable->vals[i], desc, row->values, row->nulls);
		if (!stored && !in_box(row, lr->lo, lr->hi))
			continue;
		if (lr->stats)
			lr->stats->in_box++;
		if (!stored && !lr->start && !same_pose_and_rate(r, row))
			continue;
		if (lr->ending ? !ending_filters(r, lr->ending, row) : !passes_filters(r, row))
		{
			r->refused++;
			continue;
		}
		if (lr->stats)
			lr->stats->filtered++;
		c.ratio = NAN;			/* a start follows nothing */
		if (!lr->start)
		{
			begin = terminator_of(&row->values[COL_POSITIONS - 1]);
			c.ratio = modb_continuity(&r->end, &begin, &r->plan->thresholds);
			if (!(c.ratio <= lr->high && c.ratio > lr->low))
				continue;
		}
		if (lr->stats)
			lr->stats->within++;
		c.row = row;
		c.id = DatumGetInt64(row_value(row, COL_ID, &isnull));
		if (lr->ending)
		{
			c.has_proximity = c.has_key = ending_proximity(lr->ending, row, &c.proximity);
			c.key = c.proximity;
			keep_best(lr->best, &lr->n_best, lr->need, &c);
			continue;
		}
		c.has_proximity = stored && r->plan->has_grid
			? graph_objective(r, row, &c.proximity)
			: proximity_of(r, row, &c.proximity);
		c.has_key = c.has_proximity;
		c.key = lr->start ? c.proximity : c.proximity + r->plan->continuity_weight * c.ratio;
		keep_best(lr->best, &lr->n_best, lr->need, &c);
	}
}

/* Whether the graph and collection named hold snippet id, as far as their member sets are known. */
static bool
may_be_chosen(const Request *r, int64 id)
{
	return (r->graph_members == NULL || modb_members_hold(r->graph_members, id))
		&& (r->collection_members == NULL || modb_members_hold(r->collection_members, id));
}

/* A candidate's place in the reading order, from the objective inputs and least ratio its block holds. */
static void
candidate_pending(const LevelRead *lr, const BlockCandidate *c, double least, Pending *p)
{
	const Request *r = lr->r;
	double		weight = r->plan->continuity_weight;

	p->id = c->id;
	p->block = -1;
	p->hinted = c->hinted;
	p->has_proximity = false;
	p->bound = 0;
	p->least_ratio = c->least_ratio;
	if (p->hinted && lr->ending)
	{
		/* the distance of its net translation's end from the goal, allowing for float4 as below */
		const double *inputs = c->inputs;
		double		dx = inputs[0] - lr->ending->target[0],
					dz = inputs[2] - lr->ending->target[1];

		p->has_proximity = true;
		p->bound = sqrt(dx * dx + dz * dz);
		p->bound -= ldexp(2 * Max(fabs(inputs[0]), fabs(inputs[2])), -20) + 1e-12 * (1 + p->bound);
	}
	else if (p->hinted)
	{
		const double *inputs = c->inputs;
		double		largest = 0;

		/* The row's function (proximity_of) on the float4 roundings of its values: a float4 is within
		 * 2^-24 of its value, distances and the turn move by at most what their inputs do, so the
		 * objective is within 2^-24 (sqrt(3) the largest translation + heading_weight x the heading):
		 * allowed for sixteen times over, and the double arithmetic's own rounding. */
		for (int k = 0; k < 6; k++)
			largest = Max(largest, fabs(inputs[k]));
		p->has_proximity = modb_approach_cost(inputs, inputs + 3, true, inputs[6], r->aim, r->n, r->direction,
											  r->plan->heading_weight, &p->bound);
		p->bound -= ldexp(2 * largest + fabs(r->plan->heading_weight) * fabs(inputs[6]), -20)
			+ 1e-12 * (1 + fabs(p->bound));
		/* x + y rounds monotonically in y: no key at this level is below this (nor, for a weight of
		 * at least 0, below the weight times the least ratio its term codes allow) */
		if (!lr->start)
			p->bound += weight >= 0 ? Max(least, weight * p->least_ratio) : least;
	}
}

/* The distance from the aim point to a box of translations (3 values), in the objective's coordinates. */
static double
distance_to_box(const float *lo, const float *hi, const double *aim, int n)
{
	double		sum = 0;

	for (int i = 0; i < n; i++)
	{
		int			axis = n == 3 ? i : 2 * i;	/* {x, z}: the translation's 0 and 2 */
		double		gap = aim[i] < lo[axis] ? lo[axis] - aim[i] : (aim[i] > hi[axis] ? aim[i] - hi[axis] : 0);

		sum += gap * gap;
	}
	return sqrt(sum);
}

/*
 * The least key a block's snippets can have at this level, from the bounds of their objective inputs:
 * the least of the distances from the aim to the net and future boxes, plus heading_weight times the
 * least turn from the aim's direction to a heading between the bounds, with the same allowance for
 * float4 as a candidate's (candidate_pending), plus the level's least weight x ratio.
 */
static double
block_bound(const float *lo, const float *hi, void *arg)
{
	const LevelRead *lr = arg;
	const Request *r = lr->r;
	double		weight = r->plan->continuity_weight;
	double		heading_weight = r->plan->heading_weight;
	double		largest = 0,
				turn = 0,
				bound;

	for (int k = 0; k < 6; k++)
		largest = Max(largest, Max(fabs(lo[k]), fabs(hi[k])));
	if (lr->ending)
	{
		/* the distance from the goal to the box of the net translations' ends ({x, z}) */
		bound = distance_to_box(lo, hi, lr->ending->target, 2);
		return bound - ldexp(2 * largest, -20) - 1e-12 * (1 + bound);
	}
	if ((double) hi[6] - (double) lo[6] < 2 * M_PI)
	{
		double		from = (double) lo[6] - r->direction,
					to = (double) hi[6] - r->direction;

		/* |wrap(h - direction)| is least at a multiple of 2 pi, else at an end of the interval */
		if (floor(to / (2 * M_PI)) < ceil(from / (2 * M_PI)))
			turn = Min(fabs(atan2(sin(from), cos(from))), fabs(atan2(sin(to), cos(to))));
	}
	bound = Min(distance_to_box(lo, hi, r->aim, r->n), distance_to_box(lo + 3, hi + 3, r->aim, r->n))
		+ heading_weight * turn;
	bound -= ldexp(2 * largest + fabs(heading_weight) * Max(fabs(lo[6]), fabs(hi[6])), -20) + 1e-12 * (1 + fabs(bound))
		+ 1e-9 * (1 + heading_weight);	/* sin, cos and atan2 of an end, against the row's own */
	if (lr->start)
		return bound;			/* the objective alone */
	return bound + (weight >= 0 ? weight * Max(lr->low, 0.0) : weight * lr->high);
}

/*
 * One level: of the candidates (from the blocks of a box search, or the stored transitions), those that
 * pass the box (exactly), the filters and low < ratio <= high (low is -Infinity at level 0), ranked by
 * objective + continuity_weight x ratio; the best (k - *emitted) go into the store. Blocks and
 * candidates are taken in the order of the least key they can have (a block's from the bounds of its
 * snippets' objective inputs, a candidate's from its own), a block read into its candidates when its
 * turn comes and candidates read in batches, and no further than that least key can still beat the
 * k-th best found: the rows and order are those of reading every one. A snippet in several blocks (its
 * values updated since its first block) is read once; the newest of them holds its values, so its
 * bound from that block is right and one from an older block that is too low only reads it earlier.
 */
static void
run_level(LevelRead *lr, BlockSearch *search, const int64 *stored_ids, int n_stored, int level,
		  Tuplestorestate *store, TupleDesc out, int *emitted)
{
	Request    *r = lr->r;
	double		weight = r->plan->continuity_weight;
	/* The least weight x ratio at this level: the ratio is at least 0, above low and at most high. */
	double		least = weight >= 0 ? weight * Max(lr->low, 0.0) : weight * lr->high;
	int			n_blocks = search ? modb_block_search_count(search) : 0;
	int			n = search ? n_blocks : n_stored;
	Pending    *pending = palloc(sizeof(Pending) * Max(n, 1));
	BlockCandidate found[BLOCK_SNIPPETS];
	binaryheap *heap;
	Pending    *batch;
	HASHCTL		ctl = {.keysize = sizeof(int64), .entrysize = sizeof(int64), .hcxt = CurrentMemoryContext};
	HTAB	   *read = hash_create("modb candidates read", 256, &ctl, HASH_ELEM | HASH_BLOBS | HASH_CONTEXT);
	int64		candidates = search ? 0 : n_stored;
	int			limit;
	instr_time	start,
				duration;

	if (lr->stats)
		INSTR_TIME_SET_CURRENT(start);
	for (int i = 0; i < n; i++)
	{
		Pending    *p = &pending[i];

		memset(p, 0, sizeof(Pending));
		p->block = search ? i : -1;
		p->id = search ? PG_INT64_MIN : stored_ids[i];
		p->has_proximity = search != NULL;
		p->bound = search ? modb_block_search_bound(search, i) : 0;
		p->hinted = search != NULL && isfinite(p->bound);
	}
	lr->need = r->k - *emitted;
	lr->best = palloc(sizeof(Candidate) * Max(lr->need, 1));
	lr->n_best = 0;
	/* From a heap: a call reads few of them; every unknown one of the stored transitions in its first read. */
	heap = binaryheap_allocate(Max(search ? n_blocks * (1 + BLOCK_SNIPPETS) : n, 1), pending_heap_order, NULL);
	for (int i = 0; i < n; i++)
		binaryheap_add_unordered(heap, PointerGetDatum(&pending[i]));
	binaryheap_build(heap);
	batch = palloc(sizeof(Pending) * ((search ? 0 : n) + LARGEST_BATCH));
	limit = (search ? 0 : n) + FIRST_BATCH;
	for (int size = FIRST_BATCH;; limit = size = Min(2 * size, LARGEST_BATCH))
	{
		int			n_batch = 0;

		while (!binaryheap_empty(heap) && n_batch < limit
			   && (lr->n_best < lr->need
				   || may_beat((const Pending *) DatumGetPointer(binaryheap_first(heap)), &lr->best[lr->need - 1])))
		{
			Pending    *p = (Pending *) DatumGetPointer(binaryheap_remove_first(heap));
			bool		seen;

			if (p->block >= 0)
			{
				/* a block's turn: its candidates join the queue */
				int			m = modb_block_search_read(search, p->block, found);
				Pending    *more = palloc(sizeof(Pending) * Max(m, 1));

				candidates += m;
				for (int i = 0; i < m; i++)
				{
					if (!may_be_chosen(r, found[i].id))
					{
						if (lr->stats)
							lr->stats->outside++;
						continue;
					}
					candidate_pending(lr, &found[i], least, &more[i]);
					binaryheap_add(heap, PointerGetDatum(&more[i]));
				}
				continue;
			}
			if (!may_be_chosen(r, p->id))
			{
				if (lr->stats)
					lr->stats->outside++;	/* queued before the members were known */
				continue;
			}
			hash_search(read, &p->id, HASH_ENTER, &seen);
			if (!seen)
				batch[n_batch++] = *p;
		}
		if (n_batch == 0)
			break;
		read_and_check(lr, batch, n_batch);
		if (!r->members_read && r->refused >= REFUSED_BEFORE_MEMBERS)
			read_members(r);	/* the blocks read from here on pass over those outside */
	}
	for (int i = 0; i < lr->n_best; i++)
	{
		const Candidate *c = &lr->best[i];
		Datum		values[12];
		bool		isnull[12];
		static const int columns[] = {COL_ID, COL_CLIP, COL_VERSION, COL_MIRRORED, COL_FIRST_FRAME, COL_N_FRAMES};

		for (int j = 0; j < 6; j++)
			values[j] = row_value(c->row, columns[j], &isnull[j]);
		values[6] = Float8GetDatum(c->proximity);
		isnull[6] = !c->has_proximity;
		values[7] = Int32GetDatum(level);
		isnull[7] = false;
		values[8] = Float8GetDatum(c->ratio);
		isnull[8] = lr->start;
		values[9] = row_value(c->row, COL_NET_TRANSLATION, &isnull[9]);
		values[10] = row_value(c->row, COL_NET_ROTATION, &isnull[10]);
		values[11] = row_value(c->row, COL_NET_HEADING, &isnull[11]);
		tuplestore_putvalues(store, out, values, isnull);
		(*emitted)++;
	}
	hash_destroy(read);
	if (lr->stats)
	{
		INSTR_TIME_SET_CURRENT(duration);
		INSTR_TIME_SUBTRACT(duration, start);
		lr->stats->ran = true;
		lr->stats->stored = lr->lo == NULL;
		lr->stats->candidates = candidates;
		lr->stats->returned = lr->n_best;
		lr->stats->ms = INSTR_TIME_GET_MILLISEC(duration);
		lr->stats->access = outliving(modb_describe_access(lr->query));
	}
}

/* modb.match_box: the features +- scale x half-width, + 1e-4 (float4 terminators, float8 features). */
static void
box_of(const Request *r, double scale, double *lo, double *hi, LevelStats *stats)
{
	for (int i = 0; i < N_FEATURES; i++)
	{
		lo[i] = r->features[i] - scale * r->plan->box_half_width[i] - 1e-4;
		hi[i] = r->features[i] + scale * r->plan->box_half_width[i] + 1e-4;
	}
	if (stats)
	{
		StringInfoData text;

		initStringInfo(&text);
		appendStringInfoString(&text, "(");
		for (int i = 0; i < N_FEATURES; i++)
			appendStringInfo(&text, "%s%.17g", i ? ", " : "", lo[i]);
		appendStringInfoString(&text, "),(");
		for (int i = 0; i < N_FEATURES; i++)
			appendStringInfo(&text, "%s%.17g", i ? ", " : "", hi[i]);
		appendStringInfoString(&text, ")");
		stats->box = outliving(text.data);
	}
}

/* Levels 0-3 of the reference's rule; false when they found fewer than k rows (level 4 is needed). */
/*
 * The candidates' rows by id: with the graph's cost-to-go when `stored`, restricted to the graph's snippets
 * when one is named ($2) and, when the plan names annotations ($3), to the snippets modb.annotated passes.
 * Four kept plans; the annotated ones only where the plan has annotations (0.14.0 and later), so an older
 * version's SQL, which lacks modb.annotated, never plans them.
 */
static SPIPlanPtr
candidates_query(bool stored, bool annotated)
{
	static SPIPlanPtr kept[2][2];
	Oid			types[3] = {INT8ARRAYOID, INT8OID, TEXTOID};
	const char *filter = annotated
		? " AND modb.annotated(c.clip_id, c.version, c.first_frame, c.n_frames, $3::text[])" : "";

	if (kept[stored][annotated] != NULL)	/* planned: no query text to make again */
		return kept[stored][annotated];
	if (stored)
		return modb_kept_plan(&kept[1][annotated],
							  psprintf("SELECT " CANDIDATE_COLUMNS ", ce.cost_to_go"
									   "  FROM unnest($1::bigint[]) AS n(id) JOIN modb.snippets c ON c.id = n.id"
									   "  JOIN modb.graph_transitions ce ON ce.graph_id = $2 AND ce.from_snippet = c.id"
									   "  JOIN modb.terminators b ON b.id = c.begin_terminator"
									   " WHERE EXISTS (SELECT FROM modb.graph_snippets g WHERE g.graph_id = $2 AND g.snippet_id = c.id)%s",
									   filter),
							  3, types);
	return modb_kept_plan(&kept[0][annotated],
						  psprintf("SELECT " CANDIDATE_COLUMNS
								   "  FROM unnest($1::bigint[]) AS n(id) JOIN modb.snippets c ON c.id = n.id"
								   "  JOIN modb.terminators b ON b.id = c.begin_terminator"
								   " WHERE ($2 IS NULL OR EXISTS (SELECT FROM modb.graph_snippets g"
								   "                              WHERE g.graph_id = $2 AND g.snippet_id = c.id))%s",
								   filter),
						  3, types);
}

/* Levels 0-3 of the reference's rule; false when they found fewer than k rows (level 4 is needed). */
static bool
fast_path(Request *r, Tuplestorestate *store, TupleDesc out, SelectionStats *stats)
{
	static SPIPlanPtr stored_query;
	int			emitted = 0;
	bool		stored = false;
	bool		annotated = r->plan->annotations != NULL;
	Datum		annotations = annotated ? CStringGetTextDatum(r->plan->annotations) : (Datum) 0;

	if (r->plan->has_graph && r->plan->stored_key)
	{
		Datum		args[2] = {Int64GetDatum(r->plan->graph_id), Int64GetDatum(r->prev)};
		Oid			key_types[2] = {INT8OID, INT8OID};

		modb_kept_plan(&stored_query,
					   "SELECT e.to_snippets FROM modb.graph_transitions e WHERE e.graph_id = $1 AND e.from_snippet = $2",
					   2, key_types);
		if (SPI_execute_plan(stored_query, args, NULL, true, 1) != SPI_OK_SELECT)
			elog(ERROR, "modb: reading stored transitions failed");
		if (SPI_processed == 1)
		{
			bool		isnull;
			ArrayType  *to = DatumGetArrayTypeP(SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 1, &isnull));
			LevelRead	lr = {.r = r, .graph_id = Int64GetDatum(r->plan->graph_id), .annotations = annotations,
				.low = -INFINITY, .high = 1.0, .stats = stats ? &stats->levels[0] : NULL};

			stored = true;
			if (ARR_NDIM(to) > 1 || ARR_HASNULL(to))
				elog(ERROR, "modb: a graph's stored transitions are not a list of snippets");
			lr.query = candidates_query(true, annotated);
			run_level(&lr, NULL, (const int64 *) ARR_DATA_PTR(to), ARR_NDIM(to) ? ARR_DIMS(to)[0] : 0, 0, store,
					  out, &emitted);
		}
	}
	for (int level = stored ? 1 : 0; level < N_LEVELS && emitted < r->k; level++)
	{
		double		scale = (double) (1 << level);
		double		lo[N_FEATURES],
					hi[N_FEATURES];
		BlockSearch *search;
		TermTest	test;
		bool		testing = modb_term_test(&test, &r->end, &r->plan->thresholds, scale);
		LevelRead	lr = {.r = r, .graph_id = Int64GetDatum(r->plan->graph_id), .no_graph = !r->plan->has_graph,
			.annotations = annotations, .lo = lo, .hi = hi, .low = level == 0 ? -INFINITY : scale / 2, .high = scale,
		.stats = stats ? &stats->levels[level] : NULL};

		box_of(r, scale, lo, hi, lr.stats);
		search = modb_block_search(r->blocks_relid, r->blocks_generation, r->pose_key, r->fps, lo, hi,
								   testing ? &test : NULL, BLOCK_ENDS_ANY, block_bound, &lr,
								   lr.stats ? &lr.stats->blocks : NULL);
		lr.query = candidates_query(false, annotated);
		run_level(&lr, search, NULL, 0, level, store, out, &emitted);
		modb_block_search_end(search);
	}
	return emitted >= r->k;
}

/* What a start reads instead of a previous snippet. */
static void
read_generations(Request *r)
{
	static SPIPlanPtr query;

	modb_kept_plan(&query, "SELECT " GENERATION_COLUMNS, 0, NULL);
	if (SPI_execute_plan(query, NULL, NULL, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
		elog(ERROR, "modb: reading the generations failed");
	generations_of(r, SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 1);
}

/*
 * A start (no previous snippet; 0.29.0): the reference ranks every snippet that passes the filters, of any
 * pose and rate, by its objective (modb.approach_cost) alone, level 0, no continuity. Answered from the
 * blocks of every pose, read least objective bound first, as a level reads a box: the same rows.
 */
static void
start_path(Request *r, Tuplestorestate *store, TupleDesc out, SelectionStats *stats)
{
	double		lo[N_FEATURES],
				hi[N_FEATURES];
	int			emitted = 0;
	bool		annotated = r->plan->annotations != NULL;
	BlockSearch *search;
	LevelRead	lr = {.r = r, .start = true, .graph_id = Int64GetDatum(r->plan->graph_id),
		.no_graph = !r->plan->has_graph,
		.annotations = annotated ? CStringGetTextDatum(r->plan->annotations) : (Datum) 0,
		.lo = lo, .hi = hi, .low = -INFINITY, .high = INFINITY, .stats = stats ? &stats->levels[0] : NULL};

	for (int i = 0; i < N_FEATURES; i++)
	{
		lo[i] = -INFINITY;
		hi[i] = INFINITY;
	}
	read_graph_members(r);		/* it reads every pose's blocks before its first row */
	search = modb_block_search(r->blocks_relid, r->blocks_generation, NULL, 0, lo, hi, NULL, BLOCK_ENDS_ANY,
							   block_bound, &lr, lr.stats ? &lr.stats->blocks : NULL);
	lr.query = candidates_query(false, annotated);
	run_level(&lr, search, NULL, 0, 0, store, out, &emitted);
	modb_block_search_end(search);
}

/* The rows of a reference function (its query, with the call's first nargs arguments), put into the store. */
static void
reference_rows(FunctionCallInfo fcinfo, SPIPlanPtr *slot, const char *query, int nargs, Oid *types,
			   Tuplestorestate *store, TupleDesc out)
{
	Datum		args[8];
	char		nulls[8];

	for (int i = 0; i < nargs; i++)
	{
		nulls[i] = PG_ARGISNULL(i) ? 'n' : ' ';
		args[i] = PG_ARGISNULL(i) ? (Datum) 0 : PG_GETARG_DATUM(i);
	}
	modb_kept_plan(slot, query, nargs, types);
	if (SPI_execute_plan(*slot, args, nulls, true, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: %s failed", query);
	for (uint64 i = 0; i < SPI_processed; i++)
	{
		Datum		values[12];
		bool		isnull[12];

		heap_deform_tuple(SPI_tuptable->vals[i], SPI_tuptable->tupdesc, values, isnull);
		tuplestore_putvalues(store, out, values, isnull);
	}
}

/* The reference query's answer (the rule itself), put into the store. */
static void
reference(FunctionCallInfo fcinfo, Tuplestorestate *store, TupleDesc out)
{
	static SPIPlanPtr query;
	Oid			types[6] = {INT8OID, FLOAT8ARRAYOID, INT4OID, TEXTOID, TEXTOID, INT8ARRAYOID};

	reference_rows(fcinfo, &query, "SELECT * FROM modb.select_next_snippets_reference($1, $2, $3, $4, $5, $6)", 6,
				   types, store, out);
}

void
modb_select(FunctionCallInfo fcinfo, Tuplestorestate *store, TupleDesc out, SelectionStats *stats)
{
	Request		r = {0};
	const char *reason = NULL;	/* why the reference query answers, if it does */
	bool		valid;
	int			nest_level;
	instr_time	start,
				now;

	INSTR_TIME_SET_CURRENT(start);
	valid = !PG_ARGISNULL(1) && target_ok(PG_GETARG_ARRAYTYPE_P(1), &r) && !PG_ARGISNULL(2)
		&& PG_GETARG_INT32(2) >= 1;
	if (SPI_connect() != SPI_OK_CONNECT)
		elog(ERROR, "modb: SPI_connect failed");
	/* As a function's SET clause would: no JIT for the queries below, whatever the session's jit. */
	nest_level = NewGUCNestLevel();
	(void) set_config_option("jit", "off", PGC_USERSET, PGC_S_SESSION, GUC_ACTION_SAVE, true, 0, false);
	if (!valid || !PG_ARGISNULL(4))
		check_request(fcinfo, &r.collections, &r.n_collections);	/* raises the request's error */
	r.k = PG_GETARG_INT32(2);
	r.prev = PG_ARGISNULL(0) ? 0 : PG_GETARG_INT64(0);
	if (PG_ARGISNULL(0))
		read_generations(&r);
	else if (!read_previous(&r))
	{
		check_request(fcinfo, NULL, NULL);	/* no snippet prev: its error */
		elog(ERROR, "modb: no snippet " INT64_FORMAT, r.prev);
	}
	r.plan = modb_match_plan(PG_ARGISNULL(3) ? NULL : PG_GETARG_TEXT_PP(3), r.plans_generation, r.blocks_relid,
							 r.extension_version);
	if (stats)
	{
		INSTR_TIME_SET_CURRENT(now);
		INSTR_TIME_SUBTRACT(now, start);
		stats->plan = r.plan;
		stats->plan_ms = INSTR_TIME_GET_MILLISEC(now);
	}
	if (r.plan->has_graph && r.plan->graph_lookahead && !r.plan->has_grid && !PG_ARGISNULL(0))
		reason = "graph_lookahead, with a graph that has no cost-to-go";
	else
	{
		if (!PG_ARGISNULL(5))
			read_excluded(&r, PG_GETARG_DATUM(5));
		r.graph_rows = true;
		modb_aim_point(r.target, r.n, r.plan->has_lookahead, r.plan->lookahead, r.aim);
		r.direction = modb_aim_direction(r.aim, r.n);
		if (PG_ARGISNULL(0))
			start_path(&r, store, out, stats);	/* a start: every snippet, its objective alone */
		else if (!fast_path(&r, store, out, stats))
		{
			tuplestore_clear(store);
			reason = "levels 0-3 found fewer than k rows: level 4 (the nearest start) is needed";
		}
	}
	if (reason != NULL)
		reference(fcinfo, store, out);
	AtEOXact_GUC(true, nest_level);
	SPI_finish();
	if (stats)
	{
		INSTR_TIME_SET_CURRENT(now);
		INSTR_TIME_SUBTRACT(now, start);
		stats->total_ms = INSTR_TIME_GET_MILLISEC(now);
		stats->returned = tuplestore_tuple_count(store);
		stats->reference_reason = reason;
	}
}

Datum
modb_select_next_snippets(PG_FUNCTION_ARGS)
{
	ReturnSetInfo *rsinfo = (ReturnSetInfo *) fcinfo->resultinfo;

	InitMaterializedSRF(fcinfo, 0);
	modb_select(fcinfo, rsinfo->setResult, rsinfo->setDesc, NULL);
	return (Datum) 0;
}

/*
 * The candidates' rows for coming to rest or setting off: select_next_snippets' columns, then the ground
 * speed of the pelvis at their end, as the reference computes it ($2: no graph, always NULL).
 */
static SPIPlanPtr
ending_query(bool annotated)
{
	static SPIPlanPtr kept[2];
	Oid			types[3] = {INT8ARRAYOID, INT8OID, TEXTOID};

	if (kept[annotated] != NULL)
		return kept[annotated];
	return modb_kept_plan(&kept[annotated],
						  psprintf("SELECT " CANDIDATE_COLUMNS ", sqrt(e.velocities[1] ^ 2 + e.velocities[3] ^ 2)"
								   "  FROM unnest($1::bigint[]) AS n(id) JOIN modb.snippets c ON c.id = n.id"
								   "  JOIN modb.terminators b ON b.id = c.begin_terminator"
								   "  JOIN modb.terminators e ON e.id = c.end_terminator"
								   " WHERE $2 IS NULL%s",
								   annotated ? " AND modb.annotated(c.clip_id, c.version, c.first_frame, c.n_frames, $3::text[])"
								   : ""),
						  3, types);
}

/* The reference (select_snippet_ending_reference) answers calls the fast path does not take. */
static void
ending_reference(FunctionCallInfo fcinfo, Tuplestorestate *store, TupleDesc out)
{
	static SPIPlanPtr query;
	Oid			types[8] = {INT8OID, FLOAT8ARRAYOID, FLOAT8OID, FLOAT8ARRAYOID, TEXTOID, TEXTOID, INT8ARRAYOID, BOOLOID};

	reference_rows(fcinfo, &query, "SELECT * FROM modb.select_snippet_ending_reference($1, $2, $3, $4, $5, $6, $7, $8)",
				   8, types, store, out);
}

/*
 * modb.select_snippet_ending: coming to rest (standing) or setting off, the rule of
 * select_snippet_ending_reference (89_synthesis.sql) by the box search over the snippet blocks: for scale
 * 1, 2, 4, 8 the snippets in the scaled box that follow prev within ratio `scale` and end as wanted, the
 * least level first, then nearest the goal; the first scale that has one answers.
 */
Datum
modb_select_snippet_ending(PG_FUNCTION_ARGS)
{
	static SPIPlanPtr check;
	ReturnSetInfo *rsinfo = (ReturnSetInfo *) fcinfo->resultinfo;
	Request		r = {0};
	Ending		e = {0};
	bool		fast = true;
	int			nest_level;

	InitMaterializedSRF(fcinfo, 0);
	if (SPI_connect() != SPI_OK_CONNECT)
		elog(ERROR, "modb: SPI_connect failed");
	nest_level = NewGUCNestLevel();
	(void) set_config_option("jit", "off", PGC_USERSET, PGC_S_SESSION, GUC_ACTION_SAVE, true, 0, false);
	for (int i = 0; i < 8; i++)
		fast &= i == 4 || i == 5 || i == 6 || !PG_ARGISNULL(i);
	if (fast)
	{
		r.prev = PG_GETARG_INT64(0);
		r.k = 1;
		fast = read_previous(&r);
	}
	if (fast && !PG_ARGISNULL(6))
	{
		ArrayType  *a = PG_GETARG_ARRAYTYPE_P(6);

		fast = ARR_NDIM(a) <= 1 && !ARR_HASNULL(a);	/* a NULL id excludes every snippet there */
		e.exclude = fast && ARR_NDIM(a) == 1 ? (const int64 *) ARR_DATA_PTR(a) : NULL;
		e.n_exclude = fast && ARR_NDIM(a) == 1 ? ARR_DIMS(a)[0] : 0;
	}
	if (fast)
	{
		Oid			types[5] = {FLOAT8ARRAYOID, INT8OID, FLOAT8ARRAYOID, TEXTOID, TEXTOID};
		Datum		args[5] = {PG_GETARG_DATUM(1), PG_GETARG_DATUM(0), PG_GETARG_DATUM(3),
		PG_ARGISNULL(4) ? (Datum) 0 : PG_GETARG_DATUM(4), PG_ARGISNULL(5) ? (Datum) 0 : PG_GETARG_DATUM(5)};
		char		nulls[5] = {' ', ' ', ' ', PG_ARGISNULL(4) ? 'n' : ' ', PG_ARGISNULL(5) ? 'n' : ' '};
		bool		isnull;
		Datum		goal;
		int			n_target = 0;
		const double *target;

		/*
		 * The reference's errors, and what it reads: the goal (in the heading of prev's end terminator, as
		 * the reference reads `heading` there: the column, not the argument), the pool, the speeds.
		 */
		modb_kept_plan(&check,
					   "SELECT modb.check_world_request($1, (SELECT e.heading FROM modb.snippets s"
					   "       JOIN modb.terminators e ON e.id = s.end_terminator WHERE s.id = $2), $3),"
					   "       modb.match_plan($4) IS NOT NULL,"
					   "       CASE WHEN $5 IS NOT NULL THEN modb.collection_subtree($5) END,"
					   "       modb.rest_speed(), modb.walk_speed()",
					   5, types);
		if (SPI_execute_plan(check, args, nulls, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
			elog(ERROR, "modb: checking a request to come to rest returned nothing");
		/* Read before it is tested: an argument's order of evaluation is the compiler's (0.28.0 and before
		 * tested it first here, unset, and sent every call to the reference). */
		goal = SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 1, &isnull);
		target = float8_array(goal, isnull, &n_target);
		fast = target != NULL && n_target >= 2 && !PG_ARGISNULL(4);
		if (fast)
		{
			bool		no_ids;
			Datum		ids = SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 3, &no_ids);

			e.target[0] = target[0];
			e.target[1] = target[1];
			e.standing = PG_GETARG_BOOL(7);
			e.rest_speed = DatumGetFloat8(SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 4, &isnull));
			e.walk_speed = DatumGetFloat8(SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 5, &isnull));
			if (!no_ids && !PG_ARGISNULL(5))
			{
				ArrayType  *a = DatumGetArrayTypeP(ids);
				Datum	   *elements;
				bool	   *element_nulls;

				deconstruct_array(a, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE, &elements, &element_nulls,
								  &r.n_collections);
				r.collections = palloc(sizeof(int64) * Max(r.n_collections, 1));
				for (int i = 0; i < r.n_collections; i++)
					r.collections[i] = element_nulls[i] ? -1 : DatumGetInt64(elements[i]);
			}
			else if (!PG_ARGISNULL(5))
				fast = false;
		}
	}
	if (fast)
	{
		bool		annotated;
		int			emitted = 0;
		BlockEnds	ends = BLOCK_ENDS_ANY;

		r.plan = modb_match_plan(PG_GETARG_TEXT_PP(4), r.plans_generation, r.blocks_relid, r.extension_version);
		annotated = r.plan->annotations != NULL;
		/* the blocks' end bounds sort snippets by the speeds of 0.29.0's modb.rest_speed and walk_speed */
		if (e.standing ? e.rest_speed == BLOCK_REST_SPEED : e.walk_speed == BLOCK_WALK_SPEED)
			ends = e.standing ? BLOCK_ENDS_STANDING : BLOCK_ENDS_WALKING;
		for (int level = 0; level < N_LEVELS && emitted == 0; level++)
		{
			double		scale = (double) (1 << level);
			double		lo[N_FEATURES],
						hi[N_FEATURES];
			BlockSearch *search;
			TermTest	test;
			bool		testing = modb_term_test(&test, &r.end, &r.plan->thresholds, scale);
			LevelRead	lr = {.r = &r, .ending = &e, .graph_id = (Datum) 0, .no_graph = true,
				.annotations = annotated ? CStringGetTextDatum(r.plan->annotations) : (Datum) 0,
				.lo = lo, .hi = hi, .low = level == 0 ? -INFINITY : scale / 2, .high = scale};

			box_of(&r, scale, lo, hi, NULL);
			search = modb_block_search(r.blocks_relid, r.blocks_generation, r.pose_key, r.fps, lo, hi,
									   testing ? &test : NULL, ends, block_bound, &lr, NULL);
			modb_block_search_keep(search, ending_speed_may_pass, &e);
			lr.query = ending_query(annotated);
			run_level(&lr, search, NULL, 0, level, rsinfo->setResult, rsinfo->setDesc, &emitted);
			modb_block_search_end(search);
		}
	}
	else
		ending_reference(fcinfo, rsinfo->setResult, rsinfo->setDesc);
	AtEOXact_GUC(true, nest_level);
	SPI_finish();
	return (Datum) 0;
}
