/*
 * modb.pack_snippet_blocks: re-cuts the snippet blocks of a pose and rate into blocks of snippets that lie
 * near each other in feature space, whatever their clip. A load adds blocks of up to 32 consecutive
 * snippets of a clip (snippet_blocks.c), which are loose: 32 consecutive snippets of a walk cross much of
 * its cycle, so a small box meets hundreds of them. Packing splits the group's begin features k-d tree
 * fashion (each split at the median of the feature that spreads widest in units of the default profile's
 * box) into leaves of BLOCK_SNIPPETS, stored in the order of the split with their place in it
 * (pack_order), so that the directory's super boxes (block_directory.c) cover subtrees. (Splitting on the
 * term components too, or along the line through the two snippets farthest apart, made blocks looser in
 * the features, which the box tests first: more blocks met and read, BENCHMARKS.md "Every term bounded".) A packed block
 * is the one block of each of its snippets, so the objective inputs it holds are theirs: a call reads
 * its candidates in the order of their objective (selection.c).
 *
 * It runs under the generation row's lock, the lock every writer of blocks queues on: no block is added
 * while it reads the snippets and replaces the group's blocks, and it replaces only blocks its snapshot
 * sees, whose snippets it has read. Blocks stay a superset of the snippets, so packed blocks that name a
 * snippet deleted since cost a little time and nothing else.
 */
#include "postgres.h"

#include <math.h>

#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "funcapi.h"
#include "miscadmin.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/lsyscache.h"
#include "utils/memutils.h"
#include "catalog/namespace.h"
#include "nodes/makefuncs.h"

#include "extension/cube/cubedata.h"
#include "selection.h"

PG_FUNCTION_INFO_V1(modb_pack_snippet_blocks);

#define READ_BATCH 10000

typedef struct Packing
{
	int64		n;
	int64	   *ids;
	float	   *features;		/* n x N_FEATURES, float4: where to split, not the bounds */
	double		unit[N_FEATURES];	/* a feature's spread is measured in these (Infinity: never split on it) */
	BlockSource source;
	int			blocks;
} Packing;

static inline float
feature(const Packing *p, int32 i, int d)
{
	return p->features[(int64) i * N_FEATURES + d];
}

/* Reorders idx so that idx[m] holds the m-th smallest value of feature d, smaller ones before it. */
static void
select_nth(const Packing *p, int32 *idx, int n, int m, int d)
{
	int			lo = 0,
				hi = n - 1;

	while (lo < hi)
	{
		float		pivot = feature(p, idx[lo + (hi - lo) / 2], d);
		int			i = lo,
					j = hi;

		while (i <= j)
		{
			while (feature(p, idx[i], d) < pivot)
				i++;
			while (feature(p, idx[j], d) > pivot)
				j--;
			if (i <= j)
			{
				int32		t = idx[i];

				idx[i++] = idx[j];
				idx[j--] = t;
			}
		}
		if (m <= j)
			hi = j;
		else if (m >= i)
			lo = i;
		else
			break;
	}
}

static int
int64_order(const void *a, const void *b)
{
	int64		x = *(const int64 *) a,
				y = *(const int64 *) b;

	return x < y ? -1 : (x > y ? 1 : 0);
}

/*
 * Stores one leaf as a block, with its snippets' exact (float8) features and begin terminators (for its
 * term codes) read again, in a memory context of its own (a group has tens of thousands of leaves).
 */
static void
store_leaf(Packing *p, const int32 *idx, int n)
{
	static MemoryContext leaf_context;
	MemoryContext old;
	static SPIPlanPtr query;
	Oid			types[1] = {INT8ARRAYOID};
	Datum		args[1];
	Datum		id_datums[BLOCK_SNIPPETS];
	int64		ids[BLOCK_SNIPPETS];
	double		x[BLOCK_SNIPPETS][N_FEATURES];
	double		inputs[BLOCK_SNIPPETS][N_OBJECTIVE_INPUTS];
	int64		sorted[BLOCK_SNIPPETS];
	Terminator	begins[BLOCK_SNIPPETS];
	double		speeds[BLOCK_SNIPPETS];
	SPITupleTable *rows;

	if (leaf_context == NULL)
		leaf_context = AllocSetContextCreate(TopMemoryContext, "modb packed leaf", ALLOCSET_DEFAULT_SIZES);
	old = MemoryContextSwitchTo(leaf_context);
	for (int i = 0; i < n; i++)
		sorted[i] = p->ids[idx[i]];
	qsort(sorted, n, sizeof(int64), int64_order);
	for (int i = 0; i < n; i++)
		id_datums[i] = Int64GetDatum(sorted[i]);
	args[0] = PointerGetDatum(construct_array(id_datums, n, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE));
	modb_kept_plan(&query,
				   "SELECT s.id, s.begin_features, s.net_translation, s.future_translation, s.future_heading, "
				   BEGIN_TERMINATOR_COLUMNS
				   "  FROM modb.snippets s" BLOCK_ROW_JOINS
				   " WHERE s.id = ANY ($1) ORDER BY s.id",
				   1, types);
	if (SPI_execute_plan(query, args, NULL, false, 0) != SPI_OK_SELECT || SPI_processed != (uint64) n)
		elog(ERROR, "modb: the snippets of a block to pack changed while it was packed");
	rows = SPI_tuptable;
	for (int i = 0; i < n; i++)
		modb_block_row(rows->vals[i], rows->tupdesc, 2, &ids[i], x[i], inputs[i], &begins[i], &speeds[i]);
	modb_store_block(ids, (const double (*)[N_FEATURES]) x, (const double (*)[N_OBJECTIVE_INPUTS]) inputs, begins,
					 speeds, n, &p->source, p->blocks++);
	SPI_freetuptable(rows);
	MemoryContextSwitchTo(old);
	MemoryContextReset(leaf_context);
}

/* Splits idx[0..n) at the median of its widest feature until the parts fit a block; leaves in order. */
static void
split(Packing *p, int32 *idx, int n)
{
	int			widest = -1;
	double		spread = 0;
	int			half;

	CHECK_FOR_INTERRUPTS();
	if (n <= BLOCK_SNIPPETS)
	{
		store_leaf(p, idx, n);
		return;
	}
	for (int d = 0; d < N_FEATURES; d++)
	{
		float		min = feature(p, idx[0], d),
					max = min;
		double		s;

		for (int i = 1; i < n; i++)
		{
			float		v = feature(p, idx[i], d);

			min = Min(min, v);
			max = Max(max, v);
		}
		s = ((double) max - (double) min) / p->unit[d];
		if (s > spread)
		{
			spread = s;
			widest = d;
		}
	}
	/* Halves that are whole blocks, so that only the last leaf of a subtree is short. */
	half = Max(BLOCK_SNIPPETS, (n / 2) / BLOCK_SNIPPETS * BLOCK_SNIPPETS);
	if (widest >= 0)
		select_nth(p, idx, n, half, widest);
	split(p, idx, half);
	split(p, idx + half, n - half);
}

/* Reads the ids and begin features (as float4) of every snippet of the group this snapshot sees. */
static void
read_group(Packing *p)
{
	static SPIPlanPtr query;
	Oid			types[2] = {TEXTOID, FLOAT8OID};
	Datum		args[2] = {CStringGetTextDatum(p->source.pose_key), Float8GetDatum(p->source.fps)};
	Portal		cursor;
	int64		capacity = READ_BATCH;

	modb_kept_plan(&query,
				   "SELECT s.id, s.begin_features FROM modb.snippets s WHERE s.pose_key = $1 AND s.fps = $2",
				   2, types);
	p->n = 0;
	p->ids = MemoryContextAllocHuge(CurrentMemoryContext, sizeof(int64) * capacity);
	p->features = MemoryContextAllocHuge(CurrentMemoryContext, sizeof(float) * N_FEATURES * capacity);
	cursor = SPI_cursor_open(NULL, query, args, NULL, false);
	for (;;)
	{
		SPI_cursor_fetch(cursor, true, READ_BATCH);
		if (SPI_processed == 0)
			break;
		if (p->n + (int64) SPI_processed > capacity)
		{
			capacity = Max(2 * capacity, p->n + (int64) SPI_processed);
			p->ids = repalloc_huge(p->ids, sizeof(int64) * capacity);
			p->features = repalloc_huge(p->features, sizeof(float) * N_FEATURES * capacity);
		}
		for (uint64 i = 0; i < SPI_processed; i++)
		{
			HeapTuple	row = SPI_tuptable->vals[i];
			bool		isnull;
			NDBOX	   *f = DatumGetNDBOXP(SPI_getbinval(row, SPI_tuptable->tupdesc, 2, &isnull));

			if (DIM(f) != N_FEATURES)
				elog(ERROR, "modb: snippet features have %d dimensions, not %d", DIM(f), N_FEATURES);
			p->ids[p->n] = DatumGetInt64(SPI_getbinval(row, SPI_tuptable->tupdesc, 1, &isnull));
			for (int d = 0; d < N_FEATURES; d++)
				p->features[p->n * N_FEATURES + d] = (float) LL_COORD(f, d);
			p->n++;
		}
		SPI_freetuptable(SPI_tuptable);
		CHECK_FOR_INTERRUPTS();
	}
	SPI_cursor_close(cursor);
}

/* The default profile's box half-widths: a split separates what its boxes separate. */
static void
read_units(double *unit)
{
	bool		isnull;
	Datum		value;

	if (SPI_execute("SELECT (modb.match_plan('default')).box_half_width", true, 1) != SPI_OK_SELECT
		|| SPI_processed != 1)
		elog(ERROR, "modb: the default profile's box could not be read");
	value = SPI_getbinval(SPI_tuptable->vals[0], SPI_tuptable->tupdesc, 1, &isnull);
	for (int d = 0; d < N_FEATURES; d++)
		unit[d] = INFINITY;
	if (!isnull)
	{
		ArrayType  *a = DatumGetArrayTypeP(value);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == N_FEATURES)
			for (int d = 0; d < N_FEATURES; d++)
			{
				double		w = ((double *) ARR_DATA_PTR(a))[d];

				if (isfinite(w) && w > 0)
					unit[d] = w;
			}
	}
}

/* Replaces the group's blocks with packed ones; returns how many snippets they hold. */
static int64
pack_group(Packing *p)
{
	static SPIPlanPtr delete;
	Oid			types[2] = {TEXTOID, FLOAT8OID};
	Datum		args[2] = {CStringGetTextDatum(p->source.pose_key), Float8GetDatum(p->source.fps)};
	int32	   *idx;

	read_group(p);
	modb_kept_plan(&delete, "DELETE FROM modb.snippet_blocks b WHERE b.pose_key = $1 AND b.fps = $2", 2, types);
	if (SPI_execute_plan(delete, args, NULL, false, 0) != SPI_OK_DELETE)
		elog(ERROR, "modb: removing the blocks to pack failed");
	if (p->n > PG_INT32_MAX)
		elog(ERROR, "modb: more than %d snippets of one pose and rate cannot be packed", PG_INT32_MAX);
	idx = MemoryContextAllocHuge(CurrentMemoryContext, sizeof(int32) * Max(p->n, 1));
	for (int64 i = 0; i < p->n; i++)
		idx[i] = (int32) i;
	p->blocks = 0;
	if (p->n > 0)
		split(p, idx, (int) p->n);
	pfree(idx);
	pfree(p->ids);
	pfree(p->features);
	return p->n;
}

/* Whether modb.snippet_blocks has term codes (0.18.0; not a database that is not updated yet). */
static bool
has_column(const char *name)
{
	Oid			relid = RangeVarGetRelid(makeRangeVar("modb", "snippet_blocks", -1), NoLock, false);

	return get_attnum(relid, name) != InvalidAttrNumber;
}

Datum
modb_pack_snippet_blocks(PG_FUNCTION_ARGS)
{
	ReturnSetInfo *rsinfo = (ReturnSetInfo *) fcinfo->resultinfo;
	double		min_share = PG_GETARG_FLOAT8(0);
	Packing		p = {0};
	SPITupleTable *groups;
	uint64		n_groups;

	if (!(min_share >= 0 && min_share <= 1))
		ereport(ERROR, (errcode(ERRCODE_INVALID_PARAMETER_VALUE),
						errmsg("min_unpacked_share must be between 0 and 1, not %g", min_share)));
	InitMaterializedSRF(fcinfo, 0);
	if (SPI_connect() != SPI_OK_CONNECT)
		elog(ERROR, "modb: SPI_connect failed");
	/* Writers of blocks queue on this row (69_generations.sql): none adds one until this commits. */
	if (SPI_execute("SELECT FROM modb.generations WHERE name = 'snippet_blocks' FOR UPDATE", false, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: locking the snippet blocks failed");
	read_units(p.unit);
	/*
	 * A block without term codes (written before 0.18.0) or end bounds (before 0.29.0) counts as unpacked: a
	 * load derives it again.
	 */
	if (SPI_execute(psprintf("SELECT b.pose_key, b.fps,"
							 "       coalesce(sum(cardinality(b.snippets)) FILTER (WHERE b.pack_order IS NULL%s), 0),"
							 "       sum(cardinality(b.snippets))"
							 "  FROM modb.snippet_blocks b GROUP BY b.pose_key, b.fps ORDER BY b.pose_key, b.fps",
							 has_column("end_bounds") ? " OR b.term_codes IS NULL OR b.end_bounds IS NULL"
							 : has_column("term_codes") ? " OR b.term_codes IS NULL" : ""),
					false, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: reading the snippet blocks failed");
	groups = SPI_tuptable;
	n_groups = SPI_processed;
	for (uint64 g = 0; g < n_groups; g++)
	{
		HeapTuple	row = groups->vals[g];
		bool		isnull;
		int64		unpacked = DatumGetInt64(SPI_getbinval(row, groups->tupdesc, 3, &isnull));
		int64		total = DatumGetInt64(SPI_getbinval(row, groups->tupdesc, 4, &isnull));
		instr_time	start,
					duration;
		Datum		values[5];
		bool		nulls[5] = {false, false, false, false, false};

		if (min_share > 0 && (unpacked == 0 || (double) unpacked < min_share * (double) total))
			continue;			/* 0: every pose is packed (again) */
		INSTR_TIME_SET_CURRENT(start);
		p.source.pose_key = SPI_getvalue(row, groups->tupdesc, 1);
		p.source.fps = DatumGetFloat8(SPI_getbinval(row, groups->tupdesc, 2, &isnull));
		values[2] = Int64GetDatum(pack_group(&p));
		INSTR_TIME_SET_CURRENT(duration);
		INSTR_TIME_SUBTRACT(duration, start);
		values[0] = CStringGetTextDatum(p.source.pose_key);
		values[1] = Float8GetDatum(p.source.fps);
		values[3] = Int32GetDatum(p.blocks);
		values[4] = Float8GetDatum(INSTR_TIME_GET_DOUBLE(duration));
		tuplestore_putvalues(rsinfo->setResult, rsinfo->setDesc, values, nulls);
		/* An upgrade re-derives every block this way (0.18.0): progress for whoever waits on it. */
		ereport(NOTICE, (errmsg("modb: packed %lld snippets of pose %s at %g fps into %d blocks in %.1f s (group %d of %d)",
								(long long) DatumGetInt64(values[2]), p.source.pose_key, p.source.fps, p.blocks,
								INSTR_TIME_GET_DOUBLE(duration), (int) g + 1, (int) n_groups)));
	}
	SPI_finish();
	return (Datum) 0;
}
