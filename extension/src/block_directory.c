/*
 * The block directory: each snippet block's bounds, 16-bit on each feature's fixed physical scale, and the
 * bounds of its snippets' objective inputs and end bounds, by (pose, rate) group, laid out as one image
 * without pointers (about 300 bytes a block: 9 MiB at a million snippets) that the server's sessions share
 * where modb is preloaded (shared_directory.c), else kept in this session's memory; with a box over every
 * SUPER_BLOCKS consecutive blocks above them (packed blocks in the order of their packing, a subtree of its
 * split each, then the others in table order). A box search tests the groups, the super boxes and the blocks here and ranks the blocks
 * that meet the box by the least key their snippets can have; the caller reads them in that order, each
 * from modb.snippet_blocks (under the caller's snapshot, by its tuple id), whose snippets' feature codes
 * and term codes (term_codes.c) are tested: what passes is a superset of the snippets in the box whose
 * continuity ratio can be within the level, which the caller checks exactly.
 *
 * The directory is read from the covering index snippet_blocks_directory_idx (0.18.0: an index-only scan
 * of its narrow tuples, not the blocks' wide ones; the blocks themselves where a database is not updated
 * yet). It is valid for one generation of modb.snippet_blocks (71_snippet_blocks.sql): every change of
 * the blocks takes a new generation, and writers of blocks queue on the one generation row, so the
 * generation a snapshot reads names exactly the blocks it sees. A call whose snapshot reads another
 * generation (new blocks, its own uncommitted ones, an older REPEATABLE READ snapshot) reads the directory
 * again first.
 */
#include "postgres.h"

#include <math.h>

#include "access/genam.h"
#include "access/heapam.h"
#include "access/visibilitymap.h"
#include "access/tableam.h"
#include "access/detoast.h"
#include "access/relation.h"
#include "access/table.h"
#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "executor/tuptable.h"
#include "utils/lsyscache.h"
#include "storage/bufmgr.h"
#include "miscadmin.h"
#include "utils/acl.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/memutils.h"
#include "utils/rel.h"
#include "utils/snapmgr.h"

#include "selection.h"
#include "shared_directory.h"
#include "term_codes.h"

#define SUPER_BLOCKS 32
#define MaxBlockColumns 17		/* objective_inputs 12th, term_bounds 13th, term_codes 14th, end_speeds 16th,
								 * end_bounds 17th */

/* 8-bit bounds on the fixed scale met twice as many blocks as the float bounds; 16-bit ones, as many. */
#define SCALE_STEPS 65535

typedef struct Box16
{
	uint16		lo[N_FEATURES];
	uint16		hi[N_FEATURES];
} Box16;

typedef struct Entry
{
	ItemPointerData tid;
	int32		order;			/* pack_order; PG_INT32_MAX (after the packed ones) when none */
	int32		tid_order;		/* its place in the table scan */
	Box16		box;
	bool		inputs_known;	/* every snippet's objective inputs are finite (float4) */
	float		inputs_lo[N_OBJECTIVE_INPUTS];	/* their bounds over the block's snippets */
	float		inputs_hi[N_OBJECTIVE_INPUTS];
	bool		ends_known;		/* end_bounds read (a block written by 0.29.0 or later) */
	float		end_bounds[N_END_BOUNDS];
} Entry;

/* A group while the directory is read (in `building`), before it is laid out as an image. */
typedef struct PoseGroup
{
	char	   *pose_key;
	double		fps;
	int			count;			/* its blocks, in table order (a clip's blocks are stored in clip order) */
	int			capacity;
	Entry	   *entries;
	Box16	   *supers;			/* one per SUPER_BLOCKS entries */
} PoseGroup;

typedef struct Directory
{
	int			n_groups;
	int			groups_capacity;
	PoseGroup  *groups;
	int64		n_blocks;
} Directory;

static Directory directory;
static MemoryContext building;

/*
 * The directory as calls use it: one block of memory without pointers (offsets from its start), so that
 * it can be shared as it is (shared_directory.c).
 */
typedef struct ImageGroup
{
	Size		key_offset;		/* its pose_key, NUL-terminated */
	double		fps;
	int			count;
	Size		entries_offset;
	Size		supers_offset;
} ImageGroup;

typedef struct DirectoryImage
{
	Size		size;
	Oid			relid;
	Oid			relfilenode;	/* a rewrite (VACUUM FULL, CLUSTER) moves every block */
	int64		generation;
	int64		n_blocks;
	int			n_groups;
	ImageGroup	groups[FLEXIBLE_ARRAY_MEMBER];
} DirectoryImage;

static const DirectoryImage *image;	/* NULL: none yet */
static bool image_shared;		/* mapped from shared memory, not this session's own */
static MemoryContext image_context;	/* this session's own image */

#define IMAGE_AT(offset) ((const char *) image + (offset))

/* Each feature's fixed scale (build_sql.py's feature_range): code c covers min + c step. */
static const double feature_ranges[N_FEATURES][2] = FEATURE_RANGES;

static double
scale_min(int d)
{
	return feature_ranges[d][0];
}

static double
scale_step(int d)
{
	return (feature_ranges[d][1] - feature_ranges[d][0]) / SCALE_STEPS;
}

/* The codes (of `steps` steps) that values within [lo, hi] may have, with a code's margin each side. */
static void
code_range(double lo, double hi, double min, double step, int steps, int *from, int *to)
{
	double		a = floor((lo - min) / step) - 1;
	double		b = ceil((hi - min) / step) + 1;

	*from = a < -1 ? -1 : (a > steps + 1 ? steps + 1 : (int) a);
	*to = b < -1 ? -1 : (b > steps + 1 ? steps + 1 : (int) b);
}

static bool
box_meets(const Box16 *box, const int *from, const int *to)
{
	for (int d = 0; d < N_FEATURES; d++)
		if (box->hi[d] < from[d] || box->lo[d] > to[d])
			return false;
	return true;
}

static int
entry_order(const void *a, const void *b)
{
	const Entry *x = a,
			   *y = b;

	if (x->order != y->order)
		return x->order < y->order ? -1 : 1;
	return x->tid_order < y->tid_order ? -1 : (x->tid_order > y->tid_order ? 1 : 0);
}

/* The arrays a block is deformed into hold every column of this table. */
static void
check_columns(TupleDesc desc)
{
	if (desc->natts > MaxBlockColumns)
		elog(ERROR, "modb: modb.snippet_blocks has %d columns, not at most %d", desc->natts, MaxBlockColumns);
}

static void
float4_values(Datum array, float *into)
{
	ArrayType  *a = DatumGetArrayTypeP(array);

	if (ARR_NDIM(a) != 1 || ARR_HASNULL(a) || ARR_DIMS(a)[0] != N_FEATURES)
		elog(ERROR, "modb: a snippet block's bounds are not %d values", N_FEATURES);
	memcpy(into, ARR_DATA_PTR(a), sizeof(float) * N_FEATURES);
}

static PoseGroup *
group_of(const char *pose_key, int length, double fps)
{
	PoseGroup  *g;

	for (int k = directory.n_groups - 1; k >= 0; k--)
	{
		g = &directory.groups[k];
		if (g->fps == fps && strlen(g->pose_key) == length && memcmp(g->pose_key, pose_key, length) == 0)
			return g;
	}
	if (directory.n_groups == directory.groups_capacity)
	{
		directory.groups_capacity = Max(8, 2 * directory.groups_capacity);
		directory.groups = directory.groups
			? repalloc(directory.groups, sizeof(PoseGroup) * directory.groups_capacity)
			: MemoryContextAlloc(building, sizeof(PoseGroup) * directory.groups_capacity);
	}
	g = &directory.groups[directory.n_groups++];
	g->pose_key = MemoryContextAllocZero(building, length + 1);
	memcpy(g->pose_key, pose_key, length);
	g->fps = fps;
	g->count = 0;
	g->capacity = 256;
	g->entries = MemoryContextAlloc(building, sizeof(Entry) * g->capacity);
	g->supers = NULL;
	return g;
}

/* A new entry of the group of pose_key and fps, with its tuple id and its place in the packing. */
static Entry *
new_entry(text *pose_key, double fps, ItemPointer tid, bool packed, int32 order)
{
	PoseGroup  *g = group_of(VARDATA_ANY(pose_key), VARSIZE_ANY_EXHDR(pose_key), fps);
	Entry	   *e;

	if (g->count == g->capacity)
	{
		g->capacity *= 2;
		g->entries = repalloc(g->entries, sizeof(Entry) * g->capacity);
	}
	e = &g->entries[g->count];
	e->tid = *tid;
	e->order = packed ? order : PG_INT32_MAX;
	e->tid_order = g->count++;	/* its place in the scan: table order, or (pack_order, tid) in the index */
	e->inputs_known = false;
	e->ends_known = false;
	directory.n_blocks++;
	return e;
}

/* An entry's box: the block's float4 bounds coded on the fixed scale, outward. */
static void
code_box(Entry *e, Datum low_array, Datum high_array)
{
	float		low[N_FEATURES],
				high[N_FEATURES];

	float4_values(low_array, low);
	float4_values(high_array, high);
	for (int d = 0; d < N_FEATURES; d++)
	{
		/* times the reciprocal, not divided: within a code of the quotient, so one more code out */
		double		a = floor(((double) low[d] - scale_min(d)) * (1.0 / scale_step(d))) - 1;
		double		b = ceil(((double) high[d] - scale_min(d)) * (1.0 / scale_step(d))) + 1;

		e->box.lo[d] = (uint16) (a < 0 ? 0 : (a > SCALE_STEPS ? SCALE_STEPS : a));
		e->box.hi[d] = (uint16) (b < 0 ? 0 : (b > SCALE_STEPS ? SCALE_STEPS : b));
	}
}

/*
 * An entry's objective input bounds from `values` (count of them, float4): per input, the least and the
 * greatest over the values (`count` a multiple of N_OBJECTIVE_INPUTS, a snippet's inputs in a row), or
 * unknown where one is not finite.
 */
static void
bound_inputs(Entry *e, const float *x, int count)
{
	if (count <= 0 || count % N_OBJECTIVE_INPUTS != 0)
		return;
	e->inputs_known = true;
	for (int k = 0; k < N_OBJECTIVE_INPUTS; k++)
		e->inputs_lo[k] = e->inputs_hi[k] = x[k];
	for (int i = 0; i < count; i++)
	{
		e->inputs_known &= isfinite(x[i]);
		e->inputs_lo[i % N_OBJECTIVE_INPUTS] = Min(e->inputs_lo[i % N_OBJECTIVE_INPUTS], x[i]);
		e->inputs_hi[i % N_OBJECTIVE_INPUTS] = Max(e->inputs_hi[i % N_OBJECTIVE_INPUTS], x[i]);
	}
}

/* An entry's end bounds (selection.h), where the block has them. */
static void
end_bounds_of(Entry *e, Datum array, bool isnull)
{
	ArrayType  *a;

	if (isnull)
		return;
	a = DatumGetArrayTypeP(array);
	e->ends_known = ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == N_END_BOUNDS;
	if (e->ends_known)
		memcpy(e->end_bounds, ARR_DATA_PTR(a), sizeof(float) * N_END_BOUNDS);
}

static void
bound_inputs_of(Entry *e, Datum array, bool isnull)
{
	ArrayType  *a;

	if (isnull)
		return;
	a = DatumGetArrayTypeP(array);
	if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a))
		bound_inputs(e, (const float *) ARR_DATA_PTR(a), ARR_DIMS(a)[0]);
}

/*
 * The directory from snippet_blocks_directory_idx: (pose_key, fps, pack_order) INCLUDE (low, high,
 * input_bounds, end_bounds) (0.18.0 to 0.28.0: without end_bounds), an index-only scan under the caller's
 * snapshot (a heap page not all-visible has its tuple's visibility checked there, as an Index Only Scan
 * does). Blocks are never updated, only added and
 * deleted, so an index entry's tuple id is its block's. False when there is no such index.
 */
static bool
read_index(Relation rel)
{
	Oid			index_oid = get_relname_relid("snippet_blocks_directory_idx", RelationGetNamespace(rel));
	Relation	index;
	IndexScanDesc scan;
	TupleTableSlot *slot;
	Buffer		vm_buffer = InvalidBuffer;
	ItemPointer tid;
	MemoryContext per_block = AllocSetContextCreate(CurrentMemoryContext, "modb block", ALLOCSET_SMALL_SIZES);
	int			natts;

	if (!OidIsValid(index_oid))
		return false;
	index = index_open(index_oid, AccessShareLock);
	natts = RelationGetDescr(index)->natts;
	if (natts != 6 && natts != 7)
		elog(ERROR, "modb: snippet_blocks_directory_idx has %d columns, not 6 or 7", natts);
	slot = table_slot_create(rel, NULL);
	scan = index_beginscan(rel, index, GetActiveSnapshot(), 0, 0);
	scan->xs_want_itup = true;
	index_rescan(scan, NULL, 0, NULL, 0);
	while ((tid = index_getnext_tid(scan, ForwardScanDirection)) != NULL)
	{
		Datum		values[7];
		bool		nulls[7];
		MemoryContext old;
		Entry	   *e;

		CHECK_FOR_INTERRUPTS();
		if (!VM_ALL_VISIBLE(rel, ItemPointerGetBlockNumber(tid), &vm_buffer))
		{
			if (!index_fetch_heap(scan, slot))
				continue;		/* not visible to this snapshot */
			ExecClearTuple(slot);
		}
		old = MemoryContextSwitchTo(per_block);
		index_deform_tuple(scan->xs_itup, scan->xs_itupdesc, values, nulls);
		MemoryContextSwitchTo(old);
		e = new_entry(DatumGetTextPP(values[0]), DatumGetFloat8(values[1]), tid, !nulls[2],
					  nulls[2] ? 0 : DatumGetInt32(values[2]));
		code_box(e, values[3], values[4]);
		/* input_bounds holds the lows, then the highs: the inputs of a block of two snippets */
		bound_inputs_of(e, values[5], nulls[5]);
		if (natts == 7)
			end_bounds_of(e, values[6], nulls[6]);
		MemoryContextReset(per_block);
	}
	if (vm_buffer != InvalidBuffer)
		ReleaseBuffer(vm_buffer);
	index_endscan(scan);
	ExecDropSingleTupleTableSlot(slot);
	index_close(index, AccessShareLock);
	MemoryContextDelete(per_block);
	return true;
}

/* The directory from the blocks themselves (a database not updated to 0.18.0): a sequential scan. */
static void
read_table(Relation rel)
{
	TableScanDesc scan = table_beginscan(rel, GetActiveSnapshot(), 0, NULL);
	TupleDesc	desc = RelationGetDescr(rel);
	MemoryContext per_block = AllocSetContextCreate(CurrentMemoryContext, "modb block", ALLOCSET_SMALL_SIZES);
	HeapTuple	tuple;

	check_columns(desc);
	while ((tuple = heap_getnext(scan, ForwardScanDirection)) != NULL)
	{
		Datum		values[MaxBlockColumns];
		bool		nulls[MaxBlockColumns];
		MemoryContext old = MemoryContextSwitchTo(per_block);
		bool		packed;
		Entry	   *e;

		heap_deform_tuple(tuple, desc, values, nulls);
		packed = desc->natts >= 11 && !nulls[10];	/* 0.10.0: no packing */
		MemoryContextSwitchTo(old);
		e = new_entry(DatumGetTextPP(values[3]), DatumGetFloat8(values[4]), &tuple->t_self, packed,
					  packed ? DatumGetInt32(values[10]) : 0);
		code_box(e, values[7], values[8]);
		if (desc->natts >= 12)
			bound_inputs_of(e, values[11], nulls[11]);
		if (desc->natts >= 17)
			end_bounds_of(e, values[16], nulls[16]);
		MemoryContextReset(per_block);
	}
	table_endscan(scan);
	MemoryContextDelete(per_block);
}

/* The directory read laid out as one block of memory in `context`. */
static DirectoryImage *
lay_out(MemoryContext context, Oid relid, Oid relfilenode, int64 generation)
{
	Size		size = MAXALIGN(offsetof(DirectoryImage, groups) + sizeof(ImageGroup) * directory.n_groups);
	DirectoryImage *out;

	for (int k = 0; k < directory.n_groups; k++)
	{
		PoseGroup  *g = &directory.groups[k];

		size += MAXALIGN(strlen(g->pose_key) + 1) + MAXALIGN(sizeof(Entry) * g->count)
			+ MAXALIGN(sizeof(Box16) * ((g->count + SUPER_BLOCKS - 1) / SUPER_BLOCKS));
	}
	out = MemoryContextAllocHuge(context, size);
	out->size = size;
	out->relid = relid;
	out->relfilenode = relfilenode;
	out->generation = generation;
	out->n_blocks = directory.n_blocks;
	out->n_groups = directory.n_groups;
	size = MAXALIGN(offsetof(DirectoryImage, groups) + sizeof(ImageGroup) * directory.n_groups);
	for (int k = 0; k < directory.n_groups; k++)
	{
		PoseGroup  *g = &directory.groups[k];
		ImageGroup *to = &out->groups[k];
		Size		n_supers = (g->count + SUPER_BLOCKS - 1) / SUPER_BLOCKS;

		to->fps = g->fps;
		to->count = g->count;
		to->key_offset = size;
		strcpy((char *) out + size, g->pose_key);
		size += MAXALIGN(strlen(g->pose_key) + 1);
		to->entries_offset = size;
		memcpy((char *) out + size, g->entries, sizeof(Entry) * g->count);
		size += MAXALIGN(sizeof(Entry) * g->count);
		to->supers_offset = size;
		memcpy((char *) out + size, g->supers, sizeof(Box16) * n_supers);
		size += MAXALIGN(sizeof(Box16) * n_supers);
	}
	return out;
}

/* Reads every block visible to the caller's snapshot into this session's own image. */
static DirectoryImage *
read_directory(Relation rel, int64 generation)
{
	MemoryContext old;
	DirectoryImage *out;

	if (image_context == NULL)
		image_context = AllocSetContextCreate(TopMemoryContext, "modb block directory", ALLOCSET_DEFAULT_SIZES);
	/* What the reading allocates (and copies of what it reads) goes with this. */
	building = AllocSetContextCreate(CurrentMemoryContext, "modb block directory reading", ALLOCSET_DEFAULT_SIZES);
	memset(&directory, 0, sizeof(directory));
	old = MemoryContextSwitchTo(building);
	if (!read_index(rel))
		read_table(rel);
	for (int k = 0; k < directory.n_groups; k++)
	{
		PoseGroup  *g = &directory.groups[k];

		/* Stable: blocks of consecutive snippets keep their table (clip) order. */
		qsort(g->entries, g->count, sizeof(Entry), entry_order);
		g->supers = palloc(sizeof(Box16) * Max((g->count + SUPER_BLOCKS - 1) / SUPER_BLOCKS, 1));
		for (int e = 0; e < g->count; e++)
		{
			Box16	   *box = &g->entries[e].box;
			Box16	   *super = &g->supers[e / SUPER_BLOCKS];

			for (int d = 0; d < N_FEATURES; d++)
			{
				super->lo[d] = e % SUPER_BLOCKS == 0 ? box->lo[d] : Min(super->lo[d], box->lo[d]);
				super->hi[d] = e % SUPER_BLOCKS == 0 ? box->hi[d] : Max(super->hi[d], box->hi[d]);
			}
		}
	}
	MemoryContextSwitchTo(old);
	out = lay_out(image_context, RelationGetRelid(rel), rel->rd_node.relNode, generation);
	MemoryContextDelete(building);
	building = NULL;
	return out;
}

/*
 * The image for this call's blocks (relid at `generation`): the one the session holds, else the one shared
 * at that generation, else read now (and shared where it can be).
 */
static void
find_directory(Relation rel, int64 generation, BlockStats *stats)
{
	Oid			relid = RelationGetRelid(rel);
	Oid			relfilenode = rel->rd_node.relNode;
	const void *shared;
	DirectoryImage *own;

	if (image != NULL && image->relid == relid && image->generation == generation
		&& image->relfilenode == relfilenode)
		return;
	/* Let go of the old one first: the one shared next may be it again. */
	image = NULL;
	modb_shared_directory_release();
	if (image_context != NULL)
		MemoryContextReset(image_context);
	shared = modb_shared_directory_attach(relid, relfilenode, generation);
	if (shared == NULL)
	{
		own = read_directory(rel, generation);
		if (stats)
			stats->read_directory = true;
		shared = modb_shared_directory_publish(own, own->size, relid, relfilenode, generation);
		if (shared != NULL)
			MemoryContextReset(image_context);
		else
			image = own;
	}
	if (shared != NULL)
	{
		image = shared;
		image_shared = true;
	}
	else
		image_shared = false;
}

/* A box search: the blocks the directory could not reject, each with the least key its snippets can have. */
struct BlockSearch
{
	Relation	rel;
	const double *lo;
	const double *hi;
	const TermTest *test;
	BlockKeep	keep;			/* NULL, or what a candidate's end speed must pass before its term test */
	const void *keep_arg;
	BlockStats *stats;
	int			n;
	const Entry **entries;
	double	   *bounds;
};

/* A block's term bounds and codes for n snippets, or NULL (a block written before 0.18.0). */
static const uint8 *
term_columns(const Datum *values, const bool *nulls, TupleDesc desc, int n, const uint8 **codes)
{
	bytea	   *bounds,
			   *coded;

	if (desc->natts < 14 || nulls[12] || nulls[13])
		return NULL;
	bounds = DatumGetByteaPP(values[12]);
	coded = DatumGetByteaPP(values[13]);
	if (VARSIZE_ANY_EXHDR(bounds) != TERM_BOUNDS_BYTES || VARSIZE_ANY_EXHDR(coded) != n * TERM_CODE_BYTES)
		elog(ERROR, "modb: a snippet block's term codes are not those of %d snippets", n);
	*codes = (const uint8 *) VARDATA_ANY(coded);
	return (const uint8 *) VARDATA_ANY(bounds);
}

/*
 * Tests a block's snippets' codes against [lo, hi], and their term codes against `test` (NULL: none);
 * appends those that pass, with the objective inputs the block holds for them (blocks from 0.10.0 hold
 * none) and the least continuity ratio their term codes allow.
 */
static int
scan_block(const BlockSearch *search, HeapTuple tuple, BlockCandidate *out, int n_out)
{
	TupleDesc	desc = RelationGetDescr(search->rel);
	const double *lo = search->lo;
	const double *hi = search->hi;
	const TermTest *test = search->test;
	BlockStats *stats = search->stats;
	static TermBlock terms;
	const uint8 *term_bounds = NULL;
	const uint8 *term_codes = NULL;
	Datum		values[MaxBlockColumns];
	bool		nulls[MaxBlockColumns];
	ArrayType  *snippets;
	float		low[N_FEATURES],
				high[N_FEATURES];
	bytea	   *codes;
	const uint8 *code;
	int			n;
	int			from[N_FEATURES],
				to[N_FEATURES];
	const float *inputs = NULL;
	const float *speeds = NULL;

	heap_deform_tuple(tuple, desc, values, nulls);
	snippets = DatumGetArrayTypeP(values[6]);
	codes = DatumGetByteaPP(values[9]);
	code = (const uint8 *) VARDATA_ANY(codes);
	n = ARR_DIMS(snippets)[0];
	float4_values(values[7], low);
	float4_values(values[8], high);
	if (VARSIZE_ANY_EXHDR(codes) != n * N_FEATURES)
		elog(ERROR, "modb: a snippet block has %d codes for %d snippets", (int) VARSIZE_ANY_EXHDR(codes), n);
	for (int d = 0; d < N_FEATURES; d++)
	{
		double		step = ((double) high[d] - (double) low[d]) / 255.0;

		if (hi[d] < (double) low[d] || lo[d] > (double) high[d])
			return n_out;		/* the block's own bounds miss the box */
		if (step > 0)
			code_range(lo[d], hi[d], (double) low[d], step, 255, &from[d], &to[d]);
		else
		{
			from[d] = 0;
			to[d] = 255;
		}
	}
	if (test != NULL)
		term_bounds = term_columns(values, nulls, desc, n, &term_codes);
	if (term_bounds != NULL)
	{
		int			kind = modb_term_block(test, term_bounds, term_codes, &terms);

		if (kind >= 0)
		{
			if (stats)
				stats->blocks_rejected[kind]++;
			return n_out;		/* no snippet of the block can be within the level's ratio */
		}
	}
	if (desc->natts >= 16 && !nulls[15])
	{
		ArrayType  *a = DatumGetArrayTypeP(values[15]);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == n)
			speeds = (const float *) ARR_DATA_PTR(a);
	}
	if (desc->natts >= 12 && !nulls[11])
	{
		ArrayType  *a = DatumGetArrayTypeP(values[11]);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == n * N_OBJECTIVE_INPUTS)
			inputs = (const float *) ARR_DATA_PTR(a);
	}
	for (int i = 0; i < n; i++)
	{
		const uint8 *c = code + i * N_FEATURES;
		int			d = 0;
		BlockCandidate *candidate = &out[n_out];

		while (d < N_FEATURES && c[d] >= from[d] && c[d] <= to[d])
			d++;
		if (d < N_FEATURES)
			continue;
		if (stats)
			stats->in_codes++;
		if (search->keep && speeds && !search->keep(speeds[i], search->keep_arg))
			continue;			/* ends otherwise than the caller wants */
		candidate->least_ratio = 0;
		if (term_bounds != NULL)
		{
			int			kind = modb_term_snippet(test, &terms, i, &candidate->least_ratio);

			if (kind >= 0)
			{
				if (stats)
					stats->candidates_rejected[kind]++;
				continue;
			}
		}
		candidate->id = ((int64 *) ARR_DATA_PTR(snippets))[i];
		candidate->end_speed = speeds ? speeds[i] : NAN;
		/* Not yet filled futures (NaN) may be filled since: such a snippet's block says nothing of them. */
		candidate->hinted = inputs != NULL;
		for (int k = 0; k < N_OBJECTIVE_INPUTS; k++)
		{
			candidate->inputs[k] = inputs ? (double) inputs[i * N_OBJECTIVE_INPUTS + k] : NAN;
			candidate->hinted &= isfinite(candidate->inputs[k]);
		}
		n_out++;
	}
	return n_out;
}



BlockSearch *
modb_block_search(Oid relid, int64 generation, const char *pose_key, double fps, const double *lo,
				  const double *hi, const TermTest *test, BlockEnds ends, BlockBound bound, void *arg,
				  BlockStats *stats)
{
	BlockSearch *search = palloc0(sizeof(BlockSearch));
	int			capacity = 256;
	int			from[N_FEATURES],
				to[N_FEATURES];
	instr_time	start,
				end;

	INSTR_TIME_SET_CURRENT(start);
	search->rel = table_open(relid, AccessShareLock);
	/* Read directly, not through a query: check the caller's right to read it as a query would. */
	if (pg_class_aclcheck(relid, GetUserId(), ACL_SELECT) != ACLCHECK_OK)
		aclcheck_error(ACLCHECK_NO_PRIV, OBJECT_TABLE, RelationGetRelationName(search->rel));
	check_columns(RelationGetDescr(search->rel));
	find_directory(search->rel, generation, stats);
	if (stats)
	{
		stats->blocks = image->n_blocks;
		stats->shared_directory = image_shared;
	}
	search->lo = lo;
	search->hi = hi;
	search->test = test;
	search->stats = stats;
	search->entries = palloc(sizeof(Entry *) * capacity);
	search->bounds = palloc(sizeof(double) * capacity);
	for (int d = 0; d < N_FEATURES; d++)
		code_range(lo[d], hi[d], scale_min(d), scale_step(d), SCALE_STEPS, &from[d], &to[d]);
	for (int k = 0; k < image->n_groups; k++)
	{
		const ImageGroup *g = &image->groups[k];
		const Entry *entries = (const Entry *) IMAGE_AT(g->entries_offset);
		const Box16 *supers = (const Box16 *) IMAGE_AT(g->supers_offset);

		if (pose_key != NULL && (g->fps != fps || strcmp(IMAGE_AT(g->key_offset), pose_key) != 0))
			continue;			/* NULL: every pose and rate (a start) */
		for (int s = 0; s * SUPER_BLOCKS < g->count; s++)
		{
			if (!box_meets(&supers[s], from, to))
				continue;
			if (stats)
				stats->supers_met++;
			for (int e = s * SUPER_BLOCKS; e < Min(g->count, (s + 1) * SUPER_BLOCKS); e++)
			{
				const Entry *entry = &entries[e];
				const float *ending = NULL;	/* the net bounds of its snippets that end as asked */
				float		inputs_lo[N_OBJECTIVE_INPUTS],
							inputs_hi[N_OBJECTIVE_INPUTS];

				if (!box_meets(&entry->box, from, to))
					continue;
				if (stats)
					stats->blocks_met++;
				if (ends != BLOCK_ENDS_ANY && entry->ends_known)
				{
					ending = &entry->end_bounds[ends == BLOCK_ENDS_STANDING ? 0 : 4];
					if (isnan(ending[0]))
						continue;	/* none of its snippets ends as asked */
				}
				if (search->n == capacity)
				{
					capacity *= 2;
					search->entries = repalloc(search->entries, sizeof(Entry *) * capacity);
					search->bounds = repalloc(search->bounds, sizeof(double) * capacity);
				}
				search->entries[search->n] = entry;
				if (!entry->inputs_known)
				{
					search->bounds[search->n++] = -INFINITY;
					continue;
				}
				memcpy(inputs_lo, entry->inputs_lo, sizeof(inputs_lo));
				memcpy(inputs_hi, entry->inputs_hi, sizeof(inputs_hi));
				if (ending != NULL)
				{
					/* net_translation's x and z: of the snippets that can answer */
					inputs_lo[0] = ending[0];
					inputs_lo[2] = ending[1];
					inputs_hi[0] = ending[2];
					inputs_hi[2] = ending[3];
				}
				search->bounds[search->n++] = bound(inputs_lo, inputs_hi, arg);
			}
		}
	}
	if (stats)
	{
		INSTR_TIME_SET_CURRENT(end);
		INSTR_TIME_SUBTRACT(end, start);
		stats->ms += INSTR_TIME_GET_MILLISEC(end);
	}
	return search;
}

int
modb_block_search_count(const BlockSearch *search)
{
	return search->n;
}

double
modb_block_search_bound(const BlockSearch *search, int i)
{
	return search->bounds[i];
}

int
modb_block_search_read(BlockSearch *search, int i, BlockCandidate *out)
{
	HeapTupleData tuple;
	Buffer		buffer;
	int			n = 0;
	instr_time	start,
				end;

	INSTR_TIME_SET_CURRENT(start);
	if (search->stats)
		search->stats->blocks_read++;
	tuple.t_self = search->entries[i]->tid;
	if (heap_fetch(search->rel, GetActiveSnapshot(), &tuple, &buffer, false))
	{
		n = scan_block(search, &tuple, out, 0);
		ReleaseBuffer(buffer);
	}							/* else not visible to this snapshot */
	if (search->stats)
	{
		INSTR_TIME_SET_CURRENT(end);
		INSTR_TIME_SUBTRACT(end, start);
		search->stats->ms += INSTR_TIME_GET_MILLISEC(end);
	}
	return n;
}

void
modb_block_search_keep(BlockSearch *search, BlockKeep keep, const void *arg)
{
	search->keep = keep;
	search->keep_arg = arg;
}

void
modb_block_search_end(BlockSearch *search)
{
	table_close(search->rel, AccessShareLock);
}
