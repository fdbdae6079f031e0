/*
 * GiST penalty and split for the feature cube (modb.cube_feature_ops; every other support function is
 * contrib/cube's own). cube's default picks by volume, and in 49 dimensions volumes are products of 49 small
 * extents: they underflow to zero, or are zero outright where a joint never moves in some skeleton, so
 * nearly every insert sees penalty 0 and lands anywhere, and a selection's box overlaps most pages
 * (BENCHMARKS.md "Selection at scale"). Here the penalty is the growth of the sum of extents (never
 * degenerate), and a split is the R*-tree's with sums of extents for volumes: along the dimension whose
 * allowed splits (entries in order of their centres, at least 40% each side) have the least total sum of
 * extents, at the cheapest of them. A median split on the dimension of widest spread visited 34-41% more
 * index pages per selection at 10k-1M snippets (bench/box_pages.py).
 */
#include "postgres.h"

#include "access/gist.h"
#include "access/stratnum.h"
#include "utils/float.h"
#include "fmgr.h"

#include "extension/cube/cubedata.h"

PG_FUNCTION_INFO_V1(modb_cube_penalty);
PG_FUNCTION_INFO_V1(modb_cube_picksplit);

/* A box's lower and upper bounds and centre along d; a cube without dimension d is 0 there, as in cube. */
static double
low(NDBOX *box, int d)
{
	return d < DIM(box) ? Min(LL_COORD(box, d), UR_COORD(box, d)) : 0.0;
}

static double
high(NDBOX *box, int d)
{
	return d < DIM(box) ? Max(LL_COORD(box, d), UR_COORD(box, d)) : 0.0;
}

static double
centre(NDBOX *box, int d)
{
	return d < DIM(box) ? (LL_COORD(box, d) + UR_COORD(box, d)) / 2.0 : 0.0;
}

/* How much the sum of extents of `box` grows to take in `added` (missing dimensions count as 0, as in cube). */
Datum
modb_cube_penalty(PG_FUNCTION_ARGS)
{
	GISTENTRY  *origentry = (GISTENTRY *) PG_GETARG_POINTER(0);
	GISTENTRY  *newentry = (GISTENTRY *) PG_GETARG_POINTER(1);
	float	   *result = (float *) PG_GETARG_POINTER(2);
	NDBOX	   *box = DatumGetNDBOXP(origentry->key);
	NDBOX	   *added = DatumGetNDBOXP(newentry->key);
	int			dims = Max(DIM(box), DIM(added));
	double		growth = 0.0;

	for (int d = 0; d < dims; d++)
		growth += Max(low(box, d) - low(added, d), 0.0) + Max(high(added, d) - high(box, d), 0.0);
	*result = (float) growth;
	PG_RETURN_POINTER(result);
}

typedef struct
{
	OffsetNumber offset;
	double		key;
} SplitItem;

static int
compare_items(const void *a, const void *b)
{
	double		x = ((const SplitItem *) a)->key;
	double		y = ((const SplitItem *) b)->key;

	return x < y ? -1 : (x > y ? 1 : 0);
}

/* The smallest cube holding boxes[0 .. n - 1] (as cube_union does: the larger dimension count). */
static NDBOX *
bounding(NDBOX **boxes, int n)
{
	int			dims = 0;
	NDBOX	   *out;

	for (int i = 0; i < n; i++)
		dims = Max(dims, (int) DIM(boxes[i]));
	out = (NDBOX *) palloc0(CUBE_SIZE(dims));
	SET_VARSIZE(out, CUBE_SIZE(dims));
	SET_DIM(out, dims);
	for (int d = 0; d < dims; d++)
	{
		double		lo = get_float8_infinity();
		double		hi = -get_float8_infinity();

		for (int i = 0; i < n; i++)
		{
			lo = Min(lo, low(boxes[i], d));
			hi = Max(hi, high(boxes[i], d));
		}
		out->x[d] = lo;
		out->x[d + dims] = hi;
	}
	return out;
}

/*
 * The sums of extents of the boxes in order[0 .. k - 1] (prefix[k]) and in order[k .. n - 1] (suffix[k]),
 * for every k, growing one bounding box entry by entry from each end.
 */
static void
margins(NDBOX **boxes, const SplitItem *order, int n, int dims, double *prefix, double *suffix)
{
	double	   *lo = (double *) palloc(sizeof(double) * dims);
	double	   *hi = (double *) palloc(sizeof(double) * dims);

	for (int pass = 0; pass < 2; pass++)
	{
		double	   *out = pass == 0 ? prefix : suffix;

		for (int d = 0; d < dims; d++)
		{
			lo[d] = get_float8_infinity();
			hi[d] = -get_float8_infinity();
		}
		for (int step = 0; step < n; step++)
		{
			int			i = pass == 0 ? step : n - 1 - step;
			NDBOX	   *b = boxes[order[i].offset - FirstOffsetNumber];
			double		sum = 0.0;

			for (int d = 0; d < dims; d++)
			{
				lo[d] = Min(lo[d], low(b, d));
				hi[d] = Max(hi[d], high(b, d));
				sum += hi[d] - lo[d];
			}
			if (pass == 0)
				out[step + 1] = sum;
			else
				out[i] = sum;
		}
	}
	pfree(lo);
	pfree(hi);
}

Datum
modb_cube_picksplit(PG_FUNCTION_ARGS)
{
	GistEntryVector *entryvec = (GistEntryVector *) PG_GETARG_POINTER(0);
	GIST_SPLITVEC *v = (GIST_SPLITVEC *) PG_GETARG_POINTER(1);
	OffsetNumber maxoff = entryvec->n - 1;
	int			n = maxoff - FirstOffsetNumber + 1;
	NDBOX	  **boxes = (NDBOX **) palloc(sizeof(NDBOX *) * n);
	SplitItem  *items = (SplitItem *) palloc(sizeof(SplitItem) * n);
	SplitItem  *best_order = (SplitItem *) palloc(sizeof(SplitItem) * n);
	double	   *prefix = (double *) palloc(sizeof(double) * (n + 1));
	double	   *suffix = (double *) palloc(sizeof(double) * (n + 1));
	int			dims = 0;
	int			least = Max(1, (n * 2) / 5);	/* each side keeps at least 40%, as in the R*-tree */
	double		best_axis = get_float8_infinity();
	int			best_k = n / 2;
	NDBOX	  **in_order;

	for (int i = 0; i < n; i++)
	{
		boxes[i] = DatumGetNDBOXP(entryvec->vector[FirstOffsetNumber + i].key);
		dims = Max(dims, (int) DIM(boxes[i]));
	}
	/* Halves in stored order unless an axis does better (no dimensions, or sums that are all NaN). */
	for (int i = 0; i < n; i++)
		best_order[i].offset = FirstOffsetNumber + i;
	/* The R*-tree's choice of axis: the least total perimeter over the allowed splits along it. */
	for (int d = 0; d < dims; d++)
	{
		double		total = 0.0;
		double		cheapest = get_float8_infinity();
		int			cheapest_k = n / 2;

		for (int i = 0; i < n; i++)
		{
			items[i].offset = FirstOffsetNumber + i;
			items[i].key = centre(boxes[i], d);
		}
		qsort(items, n, sizeof(SplitItem), compare_items);
		margins(boxes, items, n, dims, prefix, suffix);
		for (int k = least; k <= n - least; k++)
		{
			double		both = prefix[k] + suffix[k];

			total += both;
			if (both < cheapest)
			{
				cheapest = both;
				cheapest_k = k;
			}
		}
		if (total < best_axis)
		{
			best_axis = total;
			best_k = cheapest_k;
			memcpy(best_order, items, sizeof(SplitItem) * n);
		}
	}

	v->spl_left = (OffsetNumber *) palloc(sizeof(OffsetNumber) * n);
	v->spl_right = (OffsetNumber *) palloc(sizeof(OffsetNumber) * n);
	v->spl_nleft = v->spl_nright = 0;
	in_order = (NDBOX **) palloc(sizeof(NDBOX *) * n);
	for (int i = 0; i < n; i++)
	{
		if (i < best_k)
			v->spl_left[v->spl_nleft++] = best_order[i].offset;
		else
			v->spl_right[v->spl_nright++] = best_order[i].offset;
		in_order[i] = boxes[best_order[i].offset - FirstOffsetNumber];
	}
	v->spl_ldatum = PointerGetDatum(bounding(in_order, best_k));
	v->spl_rdatum = PointerGetDatum(bounding(in_order + best_k, n - best_k));
	PG_RETURN_POINTER(v);
}
