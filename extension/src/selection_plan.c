/*
 * The match plan of the fast path: modb.match_plan(profile) (SQL, the one definition of a profile's
 * meaning) resolved once and kept for the session while nothing it depends on changes: the session's knobs,
 * and the profiles and graphs, whose every change takes a new generation (69_generations.sql) that each call
 * reads under its own snapshot, so an edit of a profile or a rebuilt graph takes effect on the next call,
 * in this transaction or after another commits.
 */
#include "postgres.h"

#include "catalog/pg_type.h"
#include "executor/spi.h"
#include "lib/stringinfo.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/memutils.h"

#include "selection.h"
#include "shared_plans.h"

#define N_CACHED 8

typedef struct CachedEntry
{
	char	   *key;
	MatchPlan	plan;
} CachedEntry;

static CachedEntry cache[N_CACHED];
static int	next_victim;

static void
copy_doubles(Datum array, double *into, int n)
{
	ArrayType  *a = DatumGetArrayTypeP(array);

	if (ARR_NDIM(a) != 1 || ARR_HASNULL(a) || ARR_DIMS(a)[0] != n || ARR_ELEMTYPE(a) != FLOAT8OID)
		elog(ERROR, "modb: a match plan array is not %d float8 values", n);
	memcpy(into, ARR_DATA_PTR(a), sizeof(double) * n);
}

static double
get_double(HeapTuple row, TupleDesc desc, int column, bool *isnull)
{
	Datum		value = SPI_getbinval(row, desc, column, isnull);

	return *isnull ? 0.0 : DatumGetFloat8(value);
}

/* Resolves the plan with modb.match_plan (which raises the errors of a bad profile) into `plan`. */
static void
resolve(text *profile, MatchPlan *plan)
{
	static SPIPlanPtr query;
	Oid			types[1] = {TEXTOID};
	Datum		args[1] = {PointerGetDatum(profile)};
	char		nulls[1] = {profile ? ' ' : 'n'};
	HeapTuple	row;
	TupleDesc	desc;
	bool		isnull;
	Datum		norm;

	modb_kept_plan(&query,
				   "SELECT p.position_threshold, p.angle_threshold, p.velocity_threshold, p.angular_velocity_threshold,"
				   "       p.norm = 'l1', p.velocity_terms, p.box_half_width, p.heading_weight, p.continuity_weight,"
				   "       p.lookahead_distance, p.graph_id, p.graph_lookahead,"
				   "       (SELECT g.data->'transition_key' = modb.transition_key(p) FROM modb.graphs g WHERE g.id = p.graph_id),"
				   "       c.grid IS NOT NULL, (c.grid->>'inner_radius')::float8, (c.grid->>'outer_radius')::float8,"
				   "       (c.grid->>'speed')::float8, (c.grid->>'rings')::int, (c.grid->>'angles')::int,"
				   "       ((c.grid->>'rings')::int - 1 - 1e-9)::float8,"
				   "       ln((c.grid->>'outer_radius')::float8 / (c.grid->>'inner_radius')::float8),"
				   "       (to_jsonb(p) - 'box_half_width')::text,"
				   /* to_jsonb: a version before 0.14.0 has no annotations in its plan (NULL then) */
				   "       CASE WHEN jsonb_typeof(to_jsonb(p)->'annotations') = 'array' THEN"
				   "            (SELECT array_agg(n)::text FROM jsonb_array_elements_text(to_jsonb(p)->'annotations') AS n) END"
				   "  FROM modb.match_plan($1) p"
				   "  LEFT JOIN LATERAL (SELECT g.data->'cost_to_go' AS grid FROM modb.graphs g"
				   "                      WHERE g.id = p.graph_id AND p.graph_cost_to_go) c ON true",
				   1, types);
	if (SPI_execute_plan(query, args, nulls, true, 1) != SPI_OK_SELECT || SPI_processed != 1)
		elog(ERROR, "modb: match_plan returned no plan");
	row = SPI_tuptable->vals[0];
	desc = SPI_tuptable->tupdesc;
	copy_doubles(SPI_getbinval(row, desc, 1, &isnull), plan->thresholds.position, N_JOINTS);
	copy_doubles(SPI_getbinval(row, desc, 2, &isnull), plan->thresholds.angle, N_JOINTS);
	copy_doubles(SPI_getbinval(row, desc, 3, &isnull), plan->thresholds.velocity, N_JOINTS);
	copy_doubles(SPI_getbinval(row, desc, 4, &isnull), plan->thresholds.angular_velocity, N_JOINTS);
	norm = SPI_getbinval(row, desc, 5, &isnull);
	plan->thresholds.l1 = !isnull && DatumGetBool(norm);
	norm = SPI_getbinval(row, desc, 6, &isnull);
	plan->thresholds.velocity_terms = !isnull && DatumGetBool(norm);
	copy_doubles(SPI_getbinval(row, desc, 7, &isnull), plan->box_half_width, N_FEATURES);
	plan->heading_weight = get_double(row, desc, 8, &isnull);
	plan->continuity_weight = get_double(row, desc, 9, &isnull);
	plan->lookahead = get_double(row, desc, 10, &isnull);
	plan->has_lookahead = !isnull;
	plan->graph_id = DatumGetInt64(SPI_getbinval(row, desc, 11, &isnull));
	plan->has_graph = !isnull;
	plan->graph_lookahead = DatumGetBool(SPI_getbinval(row, desc, 12, &isnull)) && !isnull;
	plan->stored_key = DatumGetBool(SPI_getbinval(row, desc, 13, &isnull)) && !isnull;
	plan->has_grid = DatumGetBool(SPI_getbinval(row, desc, 14, &isnull)) && !isnull;
	if (plan->has_grid)
	{
		plan->grid.inner_radius = get_double(row, desc, 15, &isnull);
		plan->grid.outer_radius = get_double(row, desc, 16, &isnull);
		plan->grid.speed = get_double(row, desc, 17, &isnull);
		plan->grid.rings = DatumGetInt32(SPI_getbinval(row, desc, 18, &isnull));
		plan->grid.angles = DatumGetInt32(SPI_getbinval(row, desc, 19, &isnull));
		plan->grid.last_ring = get_double(row, desc, 20, &isnull);
		plan->grid.log_radius_ratio = get_double(row, desc, 21, &isnull);
	}
	plan->shown = MemoryContextStrdup(TopMemoryContext, SPI_getvalue(row, desc, 22));
	SPI_getbinval(row, desc, 23, &isnull);
	plan->annotations = isnull ? NULL : MemoryContextStrdup(TopMemoryContext, SPI_getvalue(row, desc, 23));
}

/*
 * What the plan depends on: the profile's name, the generation of profiles and graphs, the knobs; and, for
 * a plan shared between sessions, the extension's version and its blocks' relation.
 */
static char *
plan_key(text *profile, int64 generation, Oid blocks_relid, const char *extension_version)
{
	StringInfoData key;

	initStringInfo(&key);
	appendStringInfo(&key, "%s\x1e" INT64_FORMAT "\x1e%u\x1e%s", profile ? text_to_cstring(profile) : "default",
					 generation, blocks_relid, extension_version ? extension_version : "");
	for (int i = 0; i < N_KNOBS; i++)
		appendStringInfo(&key, "\x1e%s", modb_knob_is_profile(modb_knob_value(i)) ? "" : modb_knob_value(i));
	return key.data;
}

const MatchPlan *
modb_match_plan(text *profile, int64 generation, Oid blocks_relid, const char *extension_version)
{
	char	   *key = plan_key(profile, generation, blocks_relid, extension_version);
	CachedEntry *entry;

	for (int i = 0; i < N_CACHED; i++)
		if (cache[i].key != NULL && strcmp(cache[i].key, key) == 0)
		{
			cache[i].plan.cached = true;
			cache[i].plan.shared = false;
			return &cache[i].plan;
		}
	entry = &cache[next_victim];
	next_victim = (next_victim + 1) % N_CACHED;
	if (entry->key != NULL)
	{
		pfree(entry->key);
		pfree(entry->plan.shown);
		if (entry->plan.annotations)
			pfree(entry->plan.annotations);
		entry->key = NULL;
	}
	if (modb_shared_plan_find(key, &entry->plan, TopMemoryContext))
		entry->plan.shared = true;
	else
	{
		resolve(profile, &entry->plan);	/* raises the profile's errors (no such profile included) */
		entry->plan.shared = false;
		modb_shared_plan_share(key, &entry->plan);
	}
	entry->key = MemoryContextStrdup(TopMemoryContext, key);
	entry->plan.cached = false;
	return &entry->plan;
}
