/*
 * The continuity ratio of a seam, in C: select_next_snippet scores every candidate the search box yields
 * with it, and as an inlined SQL expression over the terminators' arrays it cost ~0.1 ms a candidate
 * (BENCHMARKS.md "Selection at scale"). The arithmetic is the SQL expression's, operation for operation
 * (float4 differences widened to float8, pow(x, 2), sqrt, 4 * atan2 of the quaternion chords, the L1 sum
 * in float4), so both give the same value to the last bit and the same rows.
 */
#include "postgres.h"

#include <math.h>

#include "executor/executor.h"
#include "fmgr.h"
#include "utils/array.h"
#include "utils/builtins.h"

#include "modb.h"

PG_FUNCTION_INFO_V1(modb_continuity_ratio);

/* A one-dimensional array without NULLs of `length` elements of the given type, from a composite's field. */
static void *
field_array(HeapTupleHeader row, const char *name, Oid element, int length)
{
	bool		isnull;
	Datum		value = GetAttributeByName(row, name, &isnull);
	ArrayType  *array;

	if (isnull)
		ereport(ERROR, (errcode(ERRCODE_NULL_VALUE_NOT_ALLOWED), errmsg("continuity_ratio: %s is NULL", name)));
	array = DatumGetArrayTypeP(value);
	if (ARR_ELEMTYPE(array) != element || ARR_NDIM(array) != 1 || ARR_HASNULL(array)
		|| ARR_DIMS(array)[0] != length)
		ereport(ERROR, (errcode(ERRCODE_INVALID_PARAMETER_VALUE),
						errmsg("continuity_ratio: %s must be %d values without NULLs", name, length)));
	return ARR_DATA_PTR(array);
}

/*
 * SQL's x ^ 2 calls libm's pow(), which may differ from x * x in the last bit; a constant exponent would
 * let the compiler turn pow(x, 2.0) into x * x. But where x has at most 26 significant bits x * x is exact,
 * and so is pow (it is within 0.52 ulp of the true value, here a double): the same value, ~30x faster.
 * A difference of two float4 always qualifies, a difference of two of them widened to float8 nearly
 * always (tests/test_selection.py compares with the SQL to the last bit).
 */
static volatile double two = 2.0;

static inline double
square_exactly(double x)
{
	uint64		bits;

	memcpy(&bits, &x, sizeof(bits));
	return (bits & ((UINT64CONST(1) << 27) - 1)) == 0 ? x * x : pow(x, two);
}

static double
square(float difference)
{
	return square_exactly((double) difference);
}

/* sqrt of the sum of squared float4 differences of three components (the SQL's l2). */
static double
l2(const float *a, const float *b)
{
	return sqrt(square(a[0] - b[0]) + square(a[1] - b[1]) + square(a[2] - b[2]));
}

/* modb.quat_angle: 4 * atan2 of the smaller and larger chords between q and +-r, in float8. */
static double
quat_angle(const float *a, const float *b)
{
	double		minus = sqrt(square_exactly((double) a[0] - (double) b[0]) + square_exactly((double) a[1] - (double) b[1])
							 + square_exactly((double) a[2] - (double) b[2]) + square_exactly((double) a[3] - (double) b[3]));
	double		plus = sqrt(square_exactly((double) a[0] + (double) b[0]) + square_exactly((double) a[1] + (double) b[1])
							+ square_exactly((double) a[2] + (double) b[2]) + square_exactly((double) a[3] + (double) b[3]));

	return 4 * atan2(Min(minus, plus), Max(minus, plus));
}

double
modb_continuity(const Terminator *a, const Terminator *b, const Thresholds *t)
{
	double		ratio = -INFINITY;

	for (int j = 0; j < N_JOINTS; j++)
	{
		const float *pa = a->positions + 3 * j, *pb = b->positions + 3 * j;
		double		term;
		double		position;

		if (isinf(t->position[j]) && t->position[j] > 0)
		{
			ratio = Max(ratio, 0.0);	/* a joint the profile leaves out */
			continue;
		}
		if (t->l1)
		{
			float		sum = fabsf(pa[0] - pb[0]) + fabsf(pa[1] - pb[1]);

			sum = sum + fabsf(pa[2] - pb[2]);
			position = (double) sum;
		}
		else
			position = l2(pa, pb);
		term = Max(position / t->position[j],
				   quat_angle(a->rotations + 4 * j, b->rotations + 4 * j) / t->angle[j]);
		term = Max(term, t->velocity_terms
				   ? Max(l2(a->velocities + 3 * j, b->velocities + 3 * j) / t->velocity[j],
						 l2(a->angular_velocities + 3 * j, b->angular_velocities + 3 * j) / t->angular_velocity[j])
				   : 0.0);
		ratio = Max(ratio, term);
	}
	return ratio;
}

static Terminator
terminator_of(HeapTupleHeader row)
{
	Terminator	t;

	t.positions = field_array(row, "positions", FLOAT4OID, 3 * N_JOINTS);
	t.rotations = field_array(row, "rotations", FLOAT4OID, 4 * N_JOINTS);
	t.velocities = field_array(row, "velocities", FLOAT4OID, 3 * N_JOINTS);
	t.angular_velocities = field_array(row, "angular_velocities", FLOAT4OID, 3 * N_JOINTS);
	return t;
}

Datum
modb_continuity_ratio(PG_FUNCTION_ARGS)
{
	Terminator	a = terminator_of(PG_GETARG_HEAPTUPLEHEADER(0));
	Terminator	b = terminator_of(PG_GETARG_HEAPTUPLEHEADER(1));
	HeapTupleHeader plan = PG_GETARG_HEAPTUPLEHEADER(2);
	Thresholds	t;
	bool		isnull;
	Datum		value;

	memcpy(t.position, field_array(plan, "position_threshold", FLOAT8OID, N_JOINTS), sizeof(t.position));
	memcpy(t.angle, field_array(plan, "angle_threshold", FLOAT8OID, N_JOINTS), sizeof(t.angle));
	memcpy(t.velocity, field_array(plan, "velocity_threshold", FLOAT8OID, N_JOINTS), sizeof(t.velocity));
	memcpy(t.angular_velocity, field_array(plan, "angular_velocity_threshold", FLOAT8OID, N_JOINTS),
		   sizeof(t.angular_velocity));
	value = GetAttributeByName(plan, "norm", &isnull);
	t.l1 = !isnull && strcmp(TextDatumGetCString(value), "l1") == 0;
	value = GetAttributeByName(plan, "velocity_terms", &isnull);
	t.velocity_terms = !isnull && DatumGetBool(value);
	PG_RETURN_FLOAT8(modb_continuity(&a, &b, &t));
}
