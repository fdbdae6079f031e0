/*
 * modb.explain_selection: what a select_next_snippets call did, for the DBA who cannot see it in EXPLAIN (a
 * C function is one Function Scan there): the profile as resolved, which path answered, and per relaxation
 * level the blocks its box met, what the term codes rejected (by term kind), how its rows were read (the
 * kept query's scan nodes), how many were in the box, passed the filters, passed the continuity test and
 * were returned, and the time each stage took: a screen (lines of at most 120 characters); the profile as
 * resolved and each level's box when `verbose`.
 */
#include "postgres.h"

#include "funcapi.h"
#include "lib/stringinfo.h"
#include "miscadmin.h"
#include "utils/builtins.h"

#include "selection.h"
#include "selection_stats.h"

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
	bool		verbose = PG_NARGS() > 6 && !PG_ARGISNULL(6) && PG_GETARG_BOOL(6);

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
/* A line of at most 120 characters unless verbose (then the plan and the boxes are whole). */
#define EMIT() \
	do { if (!verbose && line.len > 120) { line.data[116] = '\0'; line.len = 116; \
			 appendStringInfoString(&line, " ..."); } \
		 value = CStringGetTextDatum(line.data); \
		 tuplestore_putvalues(rsinfo->setResult, rsinfo->setDesc, &value, &isnull); \
		 resetStringInfo(&line); } while (0)

	appendStringInfo(&line, "Selection: up to %d after snippet %s, profile \"%s\": %lld rows in %.3f ms",
					 PG_GETARG_INT32(2), PG_ARGISNULL(0) ? "none (a start)" : psprintf(INT64_FORMAT, PG_GETARG_INT64(0)),
					 PG_ARGISNULL(3) ? "default" : text_to_cstring(PG_GETARG_TEXT_PP(3)),
					 (long long) stats.returned, stats.total_ms);
	EMIT();
	if (stats.plan)
	{
		appendStringInfo(&line, "  Profile: %s (%.3f ms)",
						 stats.plan->cached ? "this session's cached plan"
						 : stats.plan->shared ? "the server's shared plan" : "resolved by modb.match_plan",
						 stats.plan_ms);
		if (verbose)
			appendStringInfo(&line, ": %s", stats.plan->shown);
	}
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
		BlockStats *b = &s->blocks;
		static const char *const kinds[N_TERM_KINDS] = TERM_KIND_NAMES;
		int64		blocks_rejected = 0,
					candidates_rejected = 0;

		if (!s->ran)
		{
			appendStringInfo(&line, "  Level %d: not run", level);
			EMIT();
			continue;
		}
		if (s->stored)
		{
			appendStringInfo(&line, "  Level 0, ratio <= 1: the graph's stored transitions: %lld candidates",
							 (long long) s->candidates);
			EMIT();
		}
		else
		{
			for (int k = 0; k < N_TERM_KINDS; k++)
			{
				blocks_rejected += b->blocks_rejected[k];
				candidates_rejected += b->candidates_rejected[k];
			}
			/* shared: the server's (shared_preload_libraries); else this session's copy */
			appendStringInfo(&line, "  Level %d, ratio <= %g: box over %lld blocks (%s directory%s): %lld super blocks, %lld blocks met it",
							 level, (double) (1 << level), (long long) b->blocks,
							 b->shared_directory ? "shared" : "session's", b->read_directory ? ", read now" : "",
							 (long long) b->supers_met,
							 (long long) b->blocks_met);
			EMIT();
			appendStringInfo(&line, "    blocks: %lld read (least key first), %lld rejected by term bounds",
							 (long long) b->blocks_read, (long long) blocks_rejected);
			EMIT();
			appendStringInfo(&line, "    snippets in the codes' box: %lld, rejected by term codes: %lld, outside the graph or collection: %lld",
							 (long long) b->in_codes, (long long) candidates_rejected, (long long) s->outside);
			EMIT();
			for (int half = 0; half < 2; half++)
			{
				appendStringInfo(&line, "    %s", half ? "                     " : "rejected (blocks/snippets):");
				for (int k = 2 * half; k < 2 * half + 2; k++)
					appendStringInfo(&line, "%s %s %lld/%lld", k % 2 ? "," : "", kinds[k],
									 (long long) b->blocks_rejected[k], (long long) b->candidates_rejected[k]);
				EMIT();
			}
		}
		appendStringInfo(&line, "    %lld candidates, %lld rows read: %lld in the box, %lld pass the filters, %lld within ratio %g, %lld returned",
						 (long long) s->candidates, (long long) s->scanned, (long long) s->in_box, (long long) s->filtered,
						 (long long) s->within, (double) (1 << level), (long long) s->returned);
		EMIT();
		appendStringInfo(&line, "    %.3f ms (block search %.3f ms); rows read by %s", s->ms, b->ms, s->access);
		EMIT();
		if (s->box && verbose)
		{
			appendStringInfo(&line, "    Box: begin_features <@ '%s'", s->box);
			EMIT();
		}
	}
	return (Datum) 0;
}
