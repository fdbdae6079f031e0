/*
 * modb.explain_selection: what a select_next_snippets call did, for the DBA who cannot see it in EXPLAIN (a
 * C function is one Function Scan there): the profile as resolved, which path answered, and per relaxation
 * level the box, how its rows were found (the kept query's scan nodes), how many rows it yielded, passed
 * the filters, passed the continuity test and were returned, and the time each stage took.
 */
#include "postgres.h"

#include "funcapi.h"
#include "lib/stringinfo.h"
#include "miscadmin.h"
#include "utils/builtins.h"

#include "selection.h"

PG_FUNCTION_INFO_V1(modb_explain_selection);

Datum
modb_explain_selection(PG_FUNCTION_ARGS)
{
	ReturnSetInfo *rsinfo = (ReturnSetInfo *) fcinfo->resultinfo;
	SelectionStats stats = {0};
	Tuplestorestate *rows;
	TupleDesc	row_desc;
	StringInfoData line;
	Datum		value;
	bool		isnull = false;

	InitMaterializedSRF(fcinfo, MAT_SRF_USE_EXPECTED_DESC);
	/* The selection's rows go to a store of their own: only the report is returned. */
	row_desc = CreateTemplateTupleDesc(12);
	{
		static const Oid types[12] = {INT8OID, INT8OID, INT4OID, BOOLOID, INT4OID, INT4OID, FLOAT8OID,
			INT4OID, FLOAT8OID, FLOAT8ARRAYOID, FLOAT8ARRAYOID, FLOAT8OID};

		for (int i = 0; i < 12; i++)
			TupleDescInitEntry(row_desc, i + 1, NULL, types[i], -1, 0);
	}
	rows = tuplestore_begin_heap(false, false, work_mem);
	modb_select(fcinfo, rows, row_desc, &stats);
	tuplestore_end(rows);

	initStringInfo(&line);
#define EMIT() \
	do { value = CStringGetTextDatum(line.data); \
		 tuplestore_putvalues(rsinfo->setResult, rsinfo->setDesc, &value, &isnull); \
		 resetStringInfo(&line); } while (0)

	appendStringInfo(&line, "Selection: up to %d after snippet %s, profile \"%s\": %lld rows in %.3f ms",
					 PG_GETARG_INT32(2), PG_ARGISNULL(0) ? "none (a start)" : psprintf(INT64_FORMAT, PG_GETARG_INT64(0)),
					 PG_ARGISNULL(3) ? "default" : text_to_cstring(PG_GETARG_TEXT_PP(3)),
					 (long long) stats.returned, stats.total_ms);
	EMIT();
	if (stats.plan)
		appendStringInfo(&line, "  Profile as resolved (%s, %.3f ms): %s",
						 stats.plan->cached ? "this session's cached plan" : "resolved by modb.match_plan",
						 stats.plan_ms, stats.plan->shown);
	else
		appendStringInfoString(&line, "  Profile: resolved by the reference query");
	EMIT();
	if (stats.reference_reason)
		appendStringInfo(&line, "  Answered by: the reference query (modb.select_next_snippets_reference), because %s",
						 stats.reference_reason);
	else
		appendStringInfoString(&line, "  Answered by: the fast path (levels 0-3 in C)");
	EMIT();
	for (int level = 0; level < N_LEVELS; level++)
	{
		LevelStats *s = &stats.levels[level];

		if (!s->ran)
		{
			appendStringInfo(&line, "  Level %d: not run", level);
			EMIT();
			continue;
		}
		if (s->stored)
			appendStringInfo(&line, "  Level 0: the graph's stored transitions: %lld candidates, %lld read by %s",
							 (long long) s->candidates, (long long) s->scanned, s->access);
		else
			appendStringInfo(&line, "  Level %d: box over %lld blocks of %lld snippets (block directory %s): "
							 "%lld blocks met it, %lld candidates from their codes (%.3f ms), "
							 "%lld read (best objective first) by %s, %lld in the box",
							 level, (long long) s->blocks.blocks, (long long) s->blocks.snippets,
							 s->blocks.read_directory ? "read now" : "cached", (long long) s->blocks.blocks_read,
							 (long long) s->candidates, s->blocks.ms, (long long) s->scanned, s->access,
							 (long long) s->in_box);
		appendStringInfo(&line, ", %lld %s, %lld within ratio %g, %lld returned (%.3f ms)",
						 (long long) s->filtered,
						 s->stored ? "in the collection and not excluded"
						 : "of the same pose and rate, in the collection and not excluded",
						 (long long) s->within, (double) (1 << level), (long long) s->returned, s->ms);
		EMIT();
		if (s->box)
		{
			appendStringInfo(&line, "    Box: begin_features <@ '%s'", s->box);
			EMIT();
		}
	}
	return (Datum) 0;
}
