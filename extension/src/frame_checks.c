/*
 * The frame checks of modb.clip_versions' constraints, in C: they read the float4 array where it lies, so
 * a clip of any length is checked in constant memory beyond the array itself (the PL/Python checks of
 * 0.8.0 and before built Python lists of the whole clip: gigabytes for a 170k-frame clip).
 */
#include "postgres.h"

#include <math.h>

#include "catalog/pg_type.h"
#include "fmgr.h"
#include "miscadmin.h"
#include "utils/array.h"

PG_FUNCTION_INFO_V1(modb_unit_quaternions_ok);
PG_FUNCTION_INFO_V1(modb_finite_ok);

/* The elements of a real[] (an error for any other element type), or NULL when it has a NULL element. */
static const float4 *
float4_elements(ArrayType *array, int *count)
{
	if (ARR_ELEMTYPE(array) != FLOAT4OID)
		ereport(ERROR, (errcode(ERRCODE_DATATYPE_MISMATCH), errmsg("modb frame checks take real[] arrays")));
	*count = ArrayGetNItems(ARR_NDIM(array), ARR_DIMS(array));
	return ARR_HASNULL(array) ? NULL : (const float4 *) ARR_DATA_PTR(array);
}

/* True when every trailing (w, x, y, z) has unit length within the tolerance and w >= 0. */
Datum
modb_unit_quaternions_ok(PG_FUNCTION_ARGS)
{
	ArrayType  *array = PG_GETARG_ARRAYTYPE_P(0);
	float8		tolerance = PG_GETARG_FLOAT8(1);
	int			count;
	const float4 *q = float4_elements(array, &count);

	if (q == NULL || count == 0 || ARR_DIMS(array)[ARR_NDIM(array) - 1] != 4)
		PG_RETURN_BOOL(false);
	for (int i = 0; i < count; i += 4)
	{
		float8		w = q[i], x = q[i + 1], y = q[i + 2], z = q[i + 3];
		float8		norm = sqrt(w * w + x * x + y * y + z * z);

		/* NaN fails every comparison, an infinity the first */
		if (!(fabs(norm - 1.0) <= tolerance) || !(w >= 0.0))
			PG_RETURN_BOOL(false);
		if ((i & 0xffff) == 0)
			CHECK_FOR_INTERRUPTS();
	}
	PG_RETURN_BOOL(true);
}

/* True when the array has no NULL, NaN or infinite element. */
Datum
modb_finite_ok(PG_FUNCTION_ARGS)
{
	ArrayType  *array = PG_GETARG_ARRAYTYPE_P(0);
	int			count;
	const float4 *v = float4_elements(array, &count);

	if (v == NULL)
		PG_RETURN_BOOL(false);
	for (int i = 0; i < count; i++)
	{
		if (!isfinite(v[i]))
			PG_RETURN_BOOL(false);
		if ((i & 0xffff) == 0)
			CHECK_FOR_INTERRUPTS();
	}
	PG_RETURN_BOOL(true);
}
