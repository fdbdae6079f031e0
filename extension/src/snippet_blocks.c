/*
 * modb.add_snippet_blocks: cuts snippets into blocks of up to BLOCK_SNIPPETS consecutive ones of a clip
 * source (71_snippet_blocks.sql) and stores, per block, the bounds of their begin features (float4, rounded
 * outward) and each snippet's 8-bit code within them. block_directory.c searches them.
 */
#include "postgres.h"

#include <math.h>

#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "utils/array.h"
#include "utils/builtins.h"

#include "extension/cube/cubedata.h"
#include "selection.h"

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

typedef struct Source
{
	int64		clip_id;
	int32		version;
	bool		mirrored;
	char	   *pose_key;
	double		fps;
	int64		collection_id;
} Source;

static void
read_source(HeapTuple row, TupleDesc desc, Source *s)
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
same_source(const Source *a, const Source *b)
{
	return a->clip_id == b->clip_id && a->version == b->version && a->mirrored == b->mirrored
		&& strcmp(a->pose_key, b->pose_key) == 0 && a->fps == b->fps && a->collection_id == b->collection_id;
}

/* Stores rows [first, first + n) of the SPI result (one source, clip order) as one block. */
static void
store_block(SPITupleTable *rows, uint64 first, int n, const Source *s)
{
	static SPIPlanPtr insert;
	Oid			types[10] = {INT8OID, INT4OID, BOOLOID, TEXTOID, FLOAT8OID, INT8OID, INT8ARRAYOID,
	FLOAT4ARRAYOID, FLOAT4ARRAYOID, BYTEAOID};
	Datum		args[10];
	Datum		ids[BLOCK_SNIPPETS];
	Datum		low[N_FEATURES],
				high[N_FEATURES];
	float		lo[N_FEATURES],
				hi[N_FEATURES];
	double		x[BLOCK_SNIPPETS][N_FEATURES];
	bytea	   *codes = palloc(VARHDRSZ + n * N_FEATURES);
	bool		isnull;

	SET_VARSIZE(codes, VARHDRSZ + n * N_FEATURES);
	for (int i = 0; i < n; i++)
	{
		HeapTuple	row = rows->vals[first + i];
		NDBOX	   *features = DatumGetNDBOXP(SPI_getbinval(row, rows->tupdesc, 8, &isnull));

		if (DIM(features) != N_FEATURES)
			elog(ERROR, "modb: snippet features have %d dimensions, not %d", DIM(features), N_FEATURES);
		ids[i] = SPI_getbinval(row, rows->tupdesc, 1, &isnull);
		for (int d = 0; d < N_FEATURES; d++)
			x[i][d] = LL_COORD(features, d);
	}
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
	args[0] = Int64GetDatum(s->clip_id);
	args[1] = Int32GetDatum(s->version);
	args[2] = BoolGetDatum(s->mirrored);
	args[3] = CStringGetTextDatum(s->pose_key);
	args[4] = Float8GetDatum(s->fps);
	args[5] = Int64GetDatum(s->collection_id);
	args[6] = PointerGetDatum(construct_array(ids, n, INT8OID, 8, FLOAT8PASSBYVAL, TYPALIGN_DOUBLE));
	args[7] = PointerGetDatum(construct_array(low, N_FEATURES, FLOAT4OID, 4, true, TYPALIGN_INT));
	args[8] = PointerGetDatum(construct_array(high, N_FEATURES, FLOAT4OID, 4, true, TYPALIGN_INT));
	args[9] = PointerGetDatum(codes);
	modb_kept_plan(&insert,
				   "INSERT INTO modb.snippet_blocks (clip_id, version, mirrored, pose_key, fps, collection_id,"
				   " snippets, low, high, codes) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
				   10, types);
	if (SPI_execute_plan(insert, args, NULL, false, 0) != SPI_OK_INSERT)
		elog(ERROR, "modb: storing a snippet block failed");
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
				   "SELECT s.id, s.clip_id, s.version, s.mirrored, s.pose_key, s.fps, s.collection_id, s.begin_features"
				   "  FROM modb.snippets s WHERE s.id = ANY ($1)"
				   " ORDER BY s.clip_id, s.version, s.mirrored, s.pose_key, s.fps, s.collection_id, s.first_frame, s.id",
				   1, types);
	if (SPI_execute_plan(query, args, NULL, false, 0) != SPI_OK_SELECT)
		elog(ERROR, "modb: reading snippets for their blocks failed");
	rows = SPI_tuptable;
	n_rows = SPI_processed;
	while (first < n_rows)
	{
		Source		source,
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
		store_block(rows, first, n, &source);
		first += n;
		blocks++;
	}
	SPI_finish();
	PG_RETURN_INT32(blocks);
}
