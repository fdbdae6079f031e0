/*
 * modb.add_snippet_blocks: cuts snippets into blocks of up to BLOCK_SNIPPETS consecutive ones of a clip
 * source (71_snippet_blocks.sql) and stores, per block, the bounds of their begin features (float4, rounded
 * outward), each snippet's 8-bit code within them, its objective's inputs and the term codes of its begin
 * terminator (term_codes.c). block_directory.c searches
 * them; pack_blocks.c re-cuts them.
 */
#include "postgres.h"

#include <math.h>

#include "catalog/namespace.h"
#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "nodes/makefuncs.h"
#include "utils/lsyscache.h"
#include "utils/array.h"
#include "utils/builtins.h"

#include "extension/cube/cubedata.h"
#include "selection.h"
#include "term_codes.h"

PG_FUNCTION_INFO_V1(modb_add_snippet_blocks);

int
modb_block_code(double x, float low, float high)
{
	double		step = ((double) high - (double) low) / 255.0;
	double		code = step > 0 ? floor((x - (double) low) / step) : 0;

	return code < 0 ? 0 : (code > 255 ? 255 : (int) code);
}

/* A float4 at or below (above) x. */
static float
float_below(double x)
{
	float		f = (float) x;

	return (double) f > x ? nextafterf(f, -INFINITY) : f;
}

static float
float_above(double x)
{
	float		f = (float) x;

	return (double) f < x ? nextafterf(f, INFINITY) : f;
}

static void
read_source(HeapTuple row, TupleDesc desc, BlockSource *s)
{
	bool		isnull;

	s->clip_id = DatumGetInt64(SPI_getbinval(row, desc, 2, &isnull));
	s->version = DatumGetInt32(SPI_getbinval(row, desc, 3, &isnull));
	s->mirrored = DatumGetBool(SPI_getbinval(row, desc, 4, &isnull));
	s->pose_key = SPI_getvalue(row, desc, 5);
	s->fps = DatumGetFloat8(SPI_getbinval(row, desc, 6, &isnull));
	s->collection_id = DatumGetInt64(SPI_getbinval(row, desc, 7, &isnull));
}

static bool
same_source(const BlockSource *a, const BlockSource *b)
{
	return a->clip_id == b->clip_id && a->version == b->version && a->mirrored == b->mirrored
		&& strcmp(a->pose_key, b->pose_key) == 0 && a->fps == b->fps && a->collection_id == b->collection_id;
}

/*
 * A block's end bounds (selection.h): the {x, z} bounds of the net translations of its snippets that end
 * standing, then of those that end walking, outward as float4; NaN where it has none, infinite where one of
 * them has no net translation. A snippet within a billionth of a speed limit counts on both sides of it.
 */
static void
end_bounds_of(const double (*inputs)[N_OBJECTIVE_INPUTS], const double *end_speeds, int n, Datum *out)
{
	for (int side = 0; side < 2; side++)
	{
		double		limit = side == 0 ? BLOCK_REST_SPEED : BLOCK_WALK_SPEED;
		double		slack = 1e-9 * limit;
		float		b[4] = {NAN, NAN, NAN, NAN};

		for (int i = 0; i < n; i++)
		{
			double		speed = end_speeds[i];
			bool		ends_so = side == 0 ? !(speed >= limit + slack) : !(speed < limit - slack);

			if (!ends_so)
				continue;
			for (int a = 0; a < 2; a++)
			{
				double		v = inputs[i][2 * a];	/* net_translation x, then z */
				float		low = isfinite(v) ? float_below(v) : -INFINITY;
				float		high = isfinite(v) ? float_above(v) : INFINITY;

				b[a] = isnan(b[a]) ? low : Min(b[a], low);
				b[2 + a] = isnan(b[2 + a]) ? high : Max(b[2 + a], high);
			}
		}
		for (int k = 0; k < 4; k++)
			out[4 * side + k] = Float4GetDatum(b[k]);
	}
}

/*
 * Stores one block: the snippets `ids` with their begin features `x`, of one clip source (`s`, with
 * pack_order < 0) or packed across the sources of s's pose and rate (pack_order its place in the packing,
 * and no clip source: pack_blocks.c).
 */
void
modb_store_block(const int64 *ids, const double (*x)[N_FEATURES], const double (*inputs)[N_OBJECTIVE_INPUTS],
				 const Terminator *begins, const double *end_speeds, int n, const BlockSource *s, int pack_order)
{
	static SPIPlanPtr insert;
	static SPIPlanPtr insert_017;
	static SPIPlanPtr insert_010;
	Oid			relid = RangeVarGetRelid(makeRangeVar("modb", "snippet_blocks", -1), NoLock, false);
	static SPIPlanPtr insert_028;
	/*
	 * A 0.10.0 database (not updated yet) has neither packing nor objective inputs, 0.17.0 no term codes,
	 * 0.28.0 no end bounds.
	 */
	bool		at_010 = get_attnum(relid, "objective_inputs") == InvalidAttrNumber;
	bool		at_017 = !at_010 && get_attnum(relid, "term_codes") == InvalidAttrNumber;
	bool		at_028 = !at_010 && !at_017 && get_attnum(relid, "end_bounds") == InvalidAttrNumber;
	Oid			types[17] = {INT8OID, INT4OID, BOOLOID, TEXTOID, FLOAT8OID, INT8OID, INT8ARRAYOID,
	FLOAT4ARRAYOID, FLOAT4ARRAYOID, BYTEAOID, INT4OID, FLOAT4ARRAYOID, BYTEAOID, BYTEAOID, FLOAT4ARRAYOID,
	FLOAT4ARRAYOID, FLOAT4ARRAYOID};
	Datum		args[17];
	char		nulls[17];
	Datum		end_bounds[N_END_BOUNDS];
	Datum		speeds[BLOCK_SNIPPETS];
	Datum		input_bounds[2 * N_OBJECTIVE_INPUTS];
	bytea	   *term_bounds = palloc(VARHDRSZ + TERM_BOUNDS_BYTES);
	bytea	   *term_codes = palloc(VARHDRSZ + n * TERM_CODE_BYTES);
	Datum		id_datums[BLOCK_SNIPPETS];
	Datum		input_datums[BLOCK_SNIPPETS * N_OBJECTIVE_INPUTS];
	Datum		low[N_FEATURES],
				high[N_FEATURES];
	float		lo[N_FEATURES],
				hi[N_FEATURES];
	bytea	   *codes = palloc(VARHDRSZ + n * N_FEATURES);

	SET_VARSIZE(codes, VARHDRSZ + n * N_FEATURES);
	for (int i = 0; i < n; i++)
		id_datums[i] = Int64GetDatum(ids[i]);
	for (int d = 0; d < N_FEATURES; d++)
	{
		double		min = x[0][d],
					max = x[0][d];

		for (int i = 1; i < n; i++)
		{
			min = Min(min, x[i][d]);
			max = Max(max, x[i][d]);
		}
		lo[d] = float_below(min);
		hi[d] = float_above(max);
		low[d] = Float4GetDatum(lo[d]);
		high[d] = Float4GetDatum(hi[d]);
	}
	for (int i = 0; i < n; i++)
		for (int d = 0; d < N_FEATURES; d++)
			((uint8 *) VARDATA(codes))[i * N_FEATURES + d] = (uint8) modb_block_code(x[i][d], lo[d], hi[d]);
	memset(nulls, ' ', sizeof(nulls));
	if (pack_order < 0)
		nulls[10] = 'n';
	else
		nulls[0] = nulls[1] = nulls[2] = nulls[5] = 'n';	/* no clip source */
	args[0] = Int64GetDatum(s->clip_id);
	args[1] = Int32GetDatum(s->version);
	args[2] = BoolGetDatum(s->mirrored);
	args[3] = CStringGetTextDatum(s->pose_key);
	args[4] = Float8GetDatum(s->fps);
	args[5] = Int64GetDatum(s->collection_id);
	args[6] = PointerGetDatum(construct_array(id_datums, n, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE));
	args[7] = PointerGetDatum(construct_array(low, N_FEATURES, FLOAT4OID, 4, true, TYPALIGN_INT));
	args[8] = PointerGetDatum(construct_array(high, N_FEATURES, FLOAT4OID, 4, true, TYPALIGN_INT));
	args[9] = PointerGetDatum(codes);
	args[10] = Int32GetDatum(pack_order);
	/* float4: two blocks fit a page; the reader allows for the rounding (selection.c) */
	for (int i = 0; i < n * N_OBJECTIVE_INPUTS; i++)
		input_datums[i] = Float4GetDatum((float) inputs[i / N_OBJECTIVE_INPUTS][i % N_OBJECTIVE_INPUTS]);
	args[11] = PointerGetDatum(construct_array(input_datums, n * N_OBJECTIVE_INPUTS, FLOAT4OID, 4, true,
											   TYPALIGN_INT));
	/* the directory's summary of them: each input's least, then each one's greatest (NULL: one not known) */
	for (int k = 0; k < N_OBJECTIVE_INPUTS; k++)
	{
		float		lo = DatumGetFloat4(input_datums[k]),
					hi = lo;

		for (int i = 0; i < n; i++)
		{
			float		v = DatumGetFloat4(input_datums[i * N_OBJECTIVE_INPUTS + k]);

			if (!isfinite(v))
				nulls[14] = 'n';
			lo = Min(lo, v);
			hi = Max(hi, v);
		}
		input_bounds[k] = Float4GetDatum(lo);
		input_bounds[N_OBJECTIVE_INPUTS + k] = Float4GetDatum(hi);
	}
	args[14] = PointerGetDatum(construct_array(input_bounds, 2 * N_OBJECTIVE_INPUTS, FLOAT4OID, 4, true, TYPALIGN_INT));
	for (int i = 0; i < n; i++)
		speeds[i] = Float4GetDatum((float) end_speeds[i]);
	args[15] = PointerGetDatum(construct_array(speeds, n, FLOAT4OID, 4, true, TYPALIGN_INT));
	end_bounds_of(inputs, end_speeds, n, end_bounds);
	args[16] = PointerGetDatum(construct_array(end_bounds, N_END_BOUNDS, FLOAT4OID, 4, true, TYPALIGN_INT));
	SET_VARSIZE(term_bounds, VARHDRSZ + TERM_BOUNDS_BYTES);
	SET_VARSIZE(term_codes, VARHDRSZ + n * TERM_CODE_BYTES);
	modb_term_encode(begins, n, (uint8 *) VARDATA(term_bounds), (uint8 *) VARDATA(term_codes));
	args[12] = PointerGetDatum(term_bounds);
	args[13] = PointerGetDatum(term_codes);
	if (at_010)
		modb_kept_plan(&insert_010,
					   "INSERT INTO modb.snippet_blocks (clip_id, version, mirrored, pose_key, fps, collection_id,"
					   " snippets, low, high, codes) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
					   10, types);
	else if (at_017)
		modb_kept_plan(&insert_017,
					   "INSERT INTO modb.snippet_blocks (clip_id, version, mirrored, pose_key, fps, collection_id,"
					   " snippets, low, high, codes, pack_order, objective_inputs)"
					   " VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)",
					   12, types);
	else if (at_028)
		modb_kept_plan(&insert_028,
					   "INSERT INTO modb.snippet_blocks (clip_id, version, mirrored, pose_key, fps, collection_id,"
					   " snippets, low, high, codes, pack_order, objective_inputs, term_bounds, term_codes, input_bounds,"
					   " end_speeds)"
					   " VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16)",
					   16, types);
	else
		modb_kept_plan(&insert,
					   "INSERT INTO modb.snippet_blocks (clip_id, version, mirrored, pose_key, fps, collection_id,"
					   " snippets, low, high, codes, pack_order, objective_inputs, term_bounds, term_codes, input_bounds,"
					   " end_speeds, end_bounds)"
					   " VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17)",
					   17, types);
	if (SPI_execute_plan(at_010 ? insert_010 : at_017 ? insert_017 : at_028 ? insert_028 : insert, args, nulls,
						 false, 0) != SPI_OK_INSERT)
		elog(ERROR, "modb: storing a snippet block failed");
}

/* A snippet row's objective inputs from its net_translation, future_translation and future_heading. */
static void
objective_inputs(Datum net, bool net_null, Datum future, bool future_null, Datum heading,
					  bool heading_null, double *inputs)
{
	for (int i = 0; i < N_OBJECTIVE_INPUTS; i++)
		inputs[i] = NAN;
	if (!net_null)
	{
		ArrayType  *a = DatumGetArrayTypeP(net);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == 3)
			memcpy(inputs, ARR_DATA_PTR(a), 3 * sizeof(double));
	}
	if (!future_null)
	{
		ArrayType  *a = DatumGetArrayTypeP(future);

		if (ARR_NDIM(a) == 1 && !ARR_HASNULL(a) && ARR_DIMS(a)[0] == 3)
			memcpy(inputs + 3, ARR_DATA_PTR(a), 3 * sizeof(double));
	}
	if (!heading_null)
		inputs[6] = DatumGetFloat8(heading);
}

/*
 * One snippet of an SPI row: its id (column 1), begin features (column `features`, a cube), objective
 * inputs (the three columns after it) and begin terminator (the four arrays after those; they live as long
 * as the row).
 */
void
modb_block_row(HeapTuple row, TupleDesc desc, int features, int64 *id, double *x, double *inputs,
			   Terminator *begin, double *end_speed)
{
	bool		isnull;
	bool		nulls[3];
	Datum		values[3];
	const float *arrays[4];
	NDBOX	   *f = DatumGetNDBOXP(SPI_getbinval(row, desc, features, &isnull));

	if (DIM(f) != N_FEATURES)
		elog(ERROR, "modb: snippet features have %d dimensions, not %d", DIM(f), N_FEATURES);
	*id = DatumGetInt64(SPI_getbinval(row, desc, 1, &isnull));
	for (int d = 0; d < N_FEATURES; d++)
		x[d] = LL_COORD(f, d);
	for (int i = 0; i < 3; i++)
		values[i] = SPI_getbinval(row, desc, features + 1 + i, &nulls[i]);
	objective_inputs(values[0], nulls[0], values[1], nulls[1], values[2], nulls[2], inputs);
	for (int i = 0; i < 4; i++)
	{
		ArrayType  *a = DatumGetArrayTypeP(SPI_getbinval(row, desc, features + 4 + i, &isnull));

		if (isnull || ARR_NDIM(a) != 1 || ARR_HASNULL(a) || ARR_DIMS(a)[0] != (i == 1 ? 4 : 3) * N_JOINTS)
			elog(ERROR, "modb: a begin terminator's arrays are not %d joints", N_JOINTS);
		arrays[i] = (const float *) ARR_DATA_PTR(a);
	}
	begin->positions = arrays[0];
	begin->rotations = arrays[1];
	begin->velocities = arrays[2];
	begin->angular_velocities = arrays[3];
	*end_speed = DatumGetFloat8(SPI_getbinval(row, desc, features + 8, &isnull));
	if (isnull)
		*end_speed = NAN;
}

/* Stores rows [first, first + n) of the SPI result (one source, clip order) as one block. */
static void
store_rows(SPITupleTable *rows, uint64 first, int n, const BlockSource *s)
{
	int64		ids[BLOCK_SNIPPETS];
	double		x[BLOCK_SNIPPETS][N_FEATURES];
	double		inputs[BLOCK_SNIPPETS][N_OBJECTIVE_INPUTS];
	Terminator	begins[BLOCK_SNIPPETS];
	double		speeds[BLOCK_SNIPPETS];

	for (int i = 0; i < n; i++)
		modb_block_row(rows->vals[first + i], rows->tupdesc, 8, &ids[i], x[i], inputs[i], &begins[i], &speeds[i]);
	modb_store_block(ids, (const double (*)[N_FEATURES]) x, (const double (*)[N_OBJECTIVE_INPUTS]) inputs, begins,
					 speeds, n, s, -1);
}

Datum
modb_add_snippet_blocks(PG_FUNCTION_ARGS)
{
	static SPIPlanPtr query;
	Oid			types[1] = {INT8ARRAYOID};
	Datum		args[1] = {PG_GETARG_DATUM(0)};
	SPITupleTable *rows;
	uint64		n_rows;
	uint64		first = 0;
	int			blocks = 0;

	if (SPI_connect() != SPI_OK_CONNECT)
		elog(ERROR, "modb: SPI_connect failed");
	modb_kept_plan(&query,
				   "SELECT s.id, s.clip_id, s.version, s.mirrored, s.pose_key, s.fps, s.collection_id, s.begin_features,"
				   "       s.net_translation, s.future_translation, s.future_heading, " BEGIN_TERMINATOR_COLUMNS
				   "  FROM modb.snippets s" BLOCK_ROW_JOINS " WHERE s.id = ANY ($1)"
				   " ORDER BY s.clip_id, s.version, s.mirrored, s.pose_key, s.fps, s.collection_id, s.first_frame, s.id",
				   1, types);
	if (SPI_execute_plan(query, args, NULL, false, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: reading snippets for their blocks failed");
	rows = SPI_tuptable;
	n_rows = SPI_processed;
	while (first < n_rows)
	{
		BlockSource source,
					next;
		int			n = 1;

		read_source(rows->vals[first], rows->tupdesc, &source);
		while (first + n < n_rows && n < BLOCK_SNIPPETS)
		{
			read_source(rows->vals[first + n], rows->tupdesc, &next);
			if (!same_source(&source, &next))
				break;
			n++;
		}
		store_rows(rows, first, n, &source);
		first += n;
		blocks++;
	}
	SPI_finish();
	PG_RETURN_INT32(blocks);
}
