/*
 * The block directory: each snippet block's bounds, 8-bit within its (pose, rate) group's range, kept in
 * this session's memory (about 110 bytes a block: 3.5 MB at a million snippets), with a box over every
 * SUPER_BLOCKS consecutive blocks above them. A box search tests the groups, the super boxes and the
 * blocks here, reads only the blocks that meet the box from modb.snippet_blocks (under the caller's
 * snapshot, by their tuple ids) and tests their snippets' codes: what passes is a superset of the
 * snippets whose features lie in the box, which the caller checks exactly.
 *
 * The directory is valid for one generation of modb.snippet_blocks (71_snippet_blocks.sql): every change
 * of the blocks takes a new generation, and writers of blocks queue on the one generation row, so the
 * generation a snapshot reads names exactly the blocks it sees. A call whose snapshot reads another
 * generation (new blocks, its own uncommitted ones, an older REPEATABLE READ snapshot) reads the directory
 * again first.
 */
#include "postgres.h"

#include <math.h>

#include "access/heapam.h"
#include "access/relation.h"
#include "access/table.h"
#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "storage/bufmgr.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/memutils.h"
#include "utils/rel.h"
#include "utils/snapmgr.h"

#include "selection.h"

#define SUPER_BLOCKS 32

typedef struct Box8
{
	uint8		lo[N_FEATURES];
	uint8		hi[N_FEATURES];
} Box8;

typedef struct Entry
{
	ItemPointerData tid;
	Box8		box;
} Entry;

typedef struct PoseGroup
{
	char	   *pose_key;
	double		fps;
	double		min[N_FEATURES];
	double		step[N_FEATURES];
	int			first;			/* its entries: entries[first .. first + count) */
	int			count;
	Box8	   *supers;			/* one per SUPER_BLOCKS entries */
} PoseGroup;

typedef struct Directory
{
	bool		valid;
	Oid			relid;
	Oid			relfilenode;	/* a rewrite (VACUUM FULL, CLUSTER) moves every block */
	int64		generation;
	int			n_groups;
	PoseGroup	   *groups;
	int			n_entries;
	Entry	   *entries;
	int64		n_snippets;
} Directory;

static Directory directory;
static MemoryContext directory_context;

static void
code_range(double lo, double hi, double min, double step, int *from, int *to)
{
	double		a = floor((lo - min) / step) - 1;
	double		b = ceil((hi - min) / step) + 1;

	*from = a < -1 ? -1 : (a > 256 ? 256 : (int) a);
	*to = b < -1 ? -1 : (b > 256 ? 256 : (int) b);
}

static bool
box8_meets(const Box8 *box, const int *from, const int *to)
{
	for (int d = 0; d < N_FEATURES; d++)
		if (box->hi[d] < from[d] || box->lo[d] > to[d])
			return false;
	return true;
}

static void
float4_values(Datum array, float *into)
{
	ArrayType  *a = DatumGetArrayTypeP(array);

	if (ARR_NDIM(a) != 1 || ARR_HASNULL(a) || ARR_DIMS(a)[0] != N_FEATURES)
		elog(ERROR, "modb: a snippet block's bounds are not %d values", N_FEATURES);
	memcpy(into, ARR_DATA_PTR(a), sizeof(float) * N_FEATURES);
}

/* Reads every block's bounds (under the caller's snapshot) into the directory. */
static void
read_directory(Oid relid, Oid relfilenode, int64 generation)
{
	static SPIPlanPtr query;
	MemoryContext old;
	SPITupleTable *rows;
	uint64		n;
	float	   *low,
			   *high;

	if (directory_context == NULL)
		directory_context = AllocSetContextCreate(TopMemoryContext, "modb block directory", ALLOCSET_DEFAULT_SIZES);
	directory.valid = false;
	MemoryContextReset(directory_context);
	modb_kept_plan(&query,
				   "SELECT b.ctid, b.pose_key, b.fps, b.low, b.high, cardinality(b.snippets) FROM modb.snippet_blocks b"
				   " ORDER BY b.pose_key, b.fps, b.clip_id, b.version, b.mirrored, b.snippets[1]",
				   0, NULL);
	if (SPI_execute_plan(query, NULL, NULL, true, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: reading the snippet blocks failed");
	rows = SPI_tuptable;
	n = SPI_processed;
	low = palloc(sizeof(float) * N_FEATURES * Max(n, 1));
	high = palloc(sizeof(float) * N_FEATURES * Max(n, 1));
	old = MemoryContextSwitchTo(directory_context);
	directory.entries = palloc(sizeof(Entry) * Max(n, 1));
	directory.groups = palloc(sizeof(PoseGroup) * Max(n, 1));
	directory.n_groups = 0;
	directory.n_snippets = 0;
	for (uint64 i = 0; i < n; i++)
	{
		HeapTuple	row = rows->vals[i];
		bool		isnull;
		char	   *pose_key = SPI_getvalue(row, rows->tupdesc, 2);
		double		fps = DatumGetFloat8(SPI_getbinval(row, rows->tupdesc, 3, &isnull));
		PoseGroup	   *g = directory.n_groups ? &directory.groups[directory.n_groups - 1] : NULL;

		directory.entries[i].tid = *(ItemPointer) DatumGetPointer(SPI_getbinval(row, rows->tupdesc, 1, &isnull));
		float4_values(SPI_getbinval(row, rows->tupdesc, 4, &isnull), low + i * N_FEATURES);
		float4_values(SPI_getbinval(row, rows->tupdesc, 5, &isnull), high + i * N_FEATURES);
		directory.n_snippets += DatumGetInt32(SPI_getbinval(row, rows->tupdesc, 6, &isnull));
		if (g == NULL || g->fps != fps || strcmp(g->pose_key, pose_key) != 0)
		{
			g = &directory.groups[directory.n_groups++];
			g->pose_key = pstrdup(pose_key);
			g->fps = fps;
			g->first = (int) i;
			g->count = 0;
		}
		g->count++;
	}
	directory.n_entries = (int) n;
	for (int k = 0; k < directory.n_groups; k++)
	{
		PoseGroup	   *g = &directory.groups[k];
		int			n_supers = (g->count + SUPER_BLOCKS - 1) / SUPER_BLOCKS;

		for (int d = 0; d < N_FEATURES; d++)
		{
			double		min = INFINITY,
						max = -INFINITY;

			for (int e = g->first; e < g->first + g->count; e++)
			{
				min = Min(min, (double) low[e * N_FEATURES + d]);
				max = Max(max, (double) high[e * N_FEATURES + d]);
			}
			g->min[d] = min;
			g->step[d] = max > min ? (max - min) / 255.0 : 1.0;
		}
		g->supers = palloc(sizeof(Box8) * Max(n_supers, 1));
		for (int e = g->first; e < g->first + g->count; e++)
		{
			Box8	   *box = &directory.entries[e].box;
			Box8	   *super = &g->supers[(e - g->first) / SUPER_BLOCKS];
			bool		first_of_super = (e - g->first) % SUPER_BLOCKS == 0;

			for (int d = 0; d < N_FEATURES; d++)
			{
				/* outward: the code box holds the block's bounds */
				double		a = floor(((double) low[e * N_FEATURES + d] - g->min[d]) / g->step[d]);
				double		b = ceil(((double) high[e * N_FEATURES + d] - g->min[d]) / g->step[d]);

				box->lo[d] = (uint8) (a < 0 ? 0 : (a > 255 ? 255 : a));
				box->hi[d] = (uint8) (b < 0 ? 0 : (b > 255 ? 255 : b));
				super->lo[d] = first_of_super ? box->lo[d] : Min(super->lo[d], box->lo[d]);
				super->hi[d] = first_of_super ? box->hi[d] : Max(super->hi[d], box->hi[d]);
			}
		}
	}
	MemoryContextSwitchTo(old);
	directory.relid = relid;
	directory.relfilenode = relfilenode;
	directory.generation = generation;
	directory.valid = true;
}

/* Tests a block's snippets' codes against [lo, hi]; appends the ids that pass. */
static int
scan_block(HeapTuple tuple, TupleDesc desc, const double *lo, const double *hi, int64 *ids, int n_ids)
{
	bool		isnull;
	ArrayType  *snippets = DatumGetArrayTypeP(heap_getattr(tuple, 7, desc, &isnull));
	float		low[N_FEATURES],
				high[N_FEATURES];
	bytea	   *codes = DatumGetByteaPP(heap_getattr(tuple, 10, desc, &isnull));
	const uint8 *code = (const uint8 *) VARDATA_ANY(codes);
	int			n = ARR_DIMS(snippets)[0];
	int			from[N_FEATURES],
				to[N_FEATURES];

	float4_values(heap_getattr(tuple, 8, desc, &isnull), low);
	float4_values(heap_getattr(tuple, 9, desc, &isnull), high);
	if (VARSIZE_ANY_EXHDR(codes) != n * N_FEATURES)
		elog(ERROR, "modb: a snippet block has %d codes for %d snippets", (int) VARSIZE_ANY_EXHDR(codes), n);
	for (int d = 0; d < N_FEATURES; d++)
	{
		double		step = ((double) high[d] - (double) low[d]) / 255.0;

		if (hi[d] < (double) low[d] || lo[d] > (double) high[d])
			return n_ids;		/* the block's own bounds miss the box */
		if (step > 0)
			code_range(lo[d], hi[d], (double) low[d], step, &from[d], &to[d]);
		else
		{
			from[d] = 0;
			to[d] = 255;
		}
	}
	for (int i = 0; i < n; i++)
	{
		const uint8 *c = code + i * N_FEATURES;
		int			d = 0;

		while (d < N_FEATURES && c[d] >= from[d] && c[d] <= to[d])
			d++;
		if (d == N_FEATURES)
			ids[n_ids++] = ((int64 *) ARR_DATA_PTR(snippets))[i];
	}
	return n_ids;
}

static int
int64_order(const void *a, const void *b)
{
	int64		x = *(const int64 *) a,
				y = *(const int64 *) b;

	return x < y ? -1 : (x > y ? 1 : 0);
}

int64 *
modb_block_candidates(Oid relid, int64 generation, const char *pose_key, double fps, const double *lo,
					  const double *hi, int *n_ids, BlockStats *stats)
{
	Relation	rel;
	int64	   *ids;
	int			n = 0,
				capacity = 1024;

	rel = table_open(relid, AccessShareLock);
	if (!directory.valid || directory.relid != relid || directory.generation != generation
		|| directory.relfilenode != rel->rd_node.relNode)
	{
		read_directory(relid, rel->rd_node.relNode, generation);
		if (stats)
			stats->read_directory = true;
	}
	if (stats)
	{
		stats->blocks = directory.n_entries;
		stats->snippets = directory.n_snippets;
	}
	ids = palloc(sizeof(int64) * capacity);
	for (int k = 0; k < directory.n_groups; k++)
	{
		PoseGroup	   *g = &directory.groups[k];
		int			from[N_FEATURES],
					to[N_FEATURES];

		if (g->fps != fps || strcmp(g->pose_key, pose_key) != 0)
			continue;
		for (int d = 0; d < N_FEATURES; d++)
			code_range(lo[d], hi[d], g->min[d], g->step[d], &from[d], &to[d]);
		for (int s = 0; s * SUPER_BLOCKS < g->count; s++)
		{
			if (!box8_meets(&g->supers[s], from, to))
				continue;
			for (int e = g->first + s * SUPER_BLOCKS; e < g->first + Min(g->count, (s + 1) * SUPER_BLOCKS); e++)
			{
				HeapTupleData tuple;
				Buffer		buffer;

				if (!box8_meets(&directory.entries[e].box, from, to))
					continue;
				if (stats)
					stats->blocks_read++;
				tuple.t_self = directory.entries[e].tid;
				if (!heap_fetch(rel, GetActiveSnapshot(), &tuple, &buffer, false))
					continue;	/* not visible to this snapshot */
				if (n + BLOCK_SNIPPETS > capacity)
				{
					capacity *= 2;
					ids = repalloc(ids, sizeof(int64) * capacity);
				}
				n = scan_block(&tuple, RelationGetDescr(rel), lo, hi, ids, n);
				ReleaseBuffer(buffer);
			}
		}
	}
	table_close(rel, AccessShareLock);
	/* A snippet in two blocks (its values updated) is one candidate. */
	qsort(ids, n, sizeof(int64), int64_order);
	*n_ids = 0;
	for (int i = 0; i < n; i++)
		if (i == 0 || ids[i] != ids[i - 1])
			ids[(*n_ids)++] = ids[i];
	return ids;
}
