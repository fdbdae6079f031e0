/*
 * GiST penalty and split for the feature cube (modb.cube_feature_ops; every other support function is
 * contrib/cube's own). cube's default picks by volume, and in 49 dimensions volumes are products of 49 small
 * extents: they underflow to zero, or are zero outright where a joint never moves in some skeleton, so
 * nearly every insert sees penalty 0 and lands anywhere, and a selection's box overlaps most pages
 * (BENCHMARKS.md "Selection at scale"). Here the penalty is the growth of the sum of extents (never
 * degenerate), and a split is a k-d tree's: at the median along the dimension where the entries' centres
 * spread the most.
 */
#include "postgres.h"

#include "access/gist.h"
#include "access/stratnum.h"
#include "utils/float.h"
#include "fmgr.h"

#include "extension/cube/cubedata.h"

PG_FUNCTION_INFO_V1(modb_cube_penalty);
PG_FUNCTION_INFO_V1(modb_cube_picksplit);

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
	{
		double		lo = d < DIM(box) ? Min(LL_COORD(box, d), UR_COORD(box, d)) : 0.0;
		double		hi = d < DIM(box) ? Max(LL_COORD(box, d), UR_COORD(box, d)) : 0.0;
		double		alo = d < DIM(added) ? Min(LL_COORD(added, d), UR_COORD(added, d)) : 0.0;
		double		ahi = d < DIM(added) ? Max(LL_COORD(added, d), UR_COORD(added, d)) : 0.0;

		growth += Max(lo - alo, 0.0) + Max(ahi - hi, 0.0);
	}
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
			NDBOX	   *b = boxes[i];
			double		l = d < DIM(b) ? Min(LL_COORD(b, d), UR_COORD(b, d)) : 0.0;
			double		u = d < DIM(b) ? Max(LL_COORD(b, d), UR_COORD(b, d)) : 0.0;

			lo = Min(lo, l);
			hi = Max(hi, u);
		}
		out->x[d] = lo;
		out->x[d + dims] = hi;
	}
	return out;
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
	int			dims = 0;
	int			best = 0;
	double		widest = -1.0;
	int			half = n / 2;

	for (int i = 0; i < n; i++)
	{
		boxes[i] = DatumGetNDBOXP(entryvec->vector[FirstOffsetNumber + i].key);
		dims = Max(dims, (int) DIM(boxes[i]));
	}
	for (int d = 0; d < dims; d++)
	{
		double		lo = get_float8_infinity();
		double		hi = -get_float8_infinity();

		for (int i = 0; i < n; i++)
		{
			double		c = centre(boxes[i], d);

			lo = Min(lo, c);
			hi = Max(hi, c);
		}
		if (hi - lo > widest)
		{
			widest = hi - lo;
			best = d;
		}
	}
	for (int i = 0; i < n; i++)
	{
		items[i].offset = FirstOffsetNumber + i;
		items[i].key = centre(boxes[i], best);
	}
	qsort(items, n, sizeof(SplitItem), compare_items);

	v->spl_left = (OffsetNumber *) palloc(sizeof(OffsetNumber) * n);
	v->spl_right = (OffsetNumber *) palloc(sizeof(OffsetNumber) * n);
	v->spl_nleft = v->spl_nright = 0;
	for (int i = 0; i < n; i++)
	{
		if (i < half)
			v->spl_left[v->spl_nleft++] = items[i].offset;
		else
			v->spl_right[v->spl_nright++] = items[i].offset;
		boxes[i] = DatumGetNDBOXP(entryvec->vector[items[i].offset].key);  /* in split order */
	}
	v->spl_ldatum = PointerGetDatum(bounding(boxes, half));
	v->spl_rdatum = PointerGetDatum(bounding(boxes + half, n - half));
	PG_RETURN_POINTER(v);
}
