/*
 * Kept SPI plans: a query planned once per session as a generic plan (the same plan whatever each call's
 * values), and how a kept plan reads its rows, for modb.explain_selection. A unit of its own so that the
 * selection and what explains it both depend on it, and not on each other.
 */
#include "postgres.h"

#include "executor/spi.h"
#include "lib/stringinfo.h"
#include "nodes/plannodes.h"
#include "parser/parsetree.h"
#include "utils/lsyscache.h"
#include "utils/plancache.h"
#include "utils/resowner.h"

#include "kept_plans.h"

SPIPlanPtr
modb_kept_plan(SPIPlanPtr *slot, const char *query, int nargs, Oid *argtypes)
{
	if (*slot == NULL)
	{
		/* Generic: planned once, not again with each call's values (plan_cache_mode auto would). */
		SPIPlanPtr	plan = SPI_prepare_cursor(query, nargs, argtypes, CURSOR_OPT_GENERIC_PLAN);

		if (plan == NULL)
			elog(ERROR, "modb: preparing a selection query failed: %s", SPI_result_code_string(SPI_result));
		SPI_keepplan(plan);
		*slot = plan;
	}
	return *slot;
}

static void
describe_node(Plan *node, List *rtable, StringInfo into)
{
	const char *kind = NULL;
	Oid			index = InvalidOid;
	Index		scanrelid = 0;

	if (node == NULL)
		return;
	switch (nodeTag(node))
	{
		case T_IndexScan:
			kind = "Index Scan";
			index = ((IndexScan *) node)->indexid;
			scanrelid = ((Scan *) node)->scanrelid;
			break;
		case T_IndexOnlyScan:
			kind = "Index Only Scan";
			index = ((IndexOnlyScan *) node)->indexid;
			scanrelid = ((Scan *) node)->scanrelid;
			break;
		case T_BitmapIndexScan:
			kind = "Bitmap Index Scan";
			index = ((BitmapIndexScan *) node)->indexid;
			break;
		case T_SeqScan:
			kind = "Seq Scan";
			scanrelid = ((Scan *) node)->scanrelid;
			break;
		default:
			break;
	}
	if (kind != NULL)
	{
		appendStringInfo(into, "%s%s", into->len ? ", " : "", kind);
		if (OidIsValid(index))
			appendStringInfo(into, " using %s", get_rel_name(index));
		if (scanrelid > 0 && rt_fetch(scanrelid, rtable)->rtekind == RTE_RELATION)
			appendStringInfo(into, " on %s", get_rel_name(rt_fetch(scanrelid, rtable)->relid));
	}
	describe_node(node->lefttree, rtable, into);
	describe_node(node->righttree, rtable, into);
}

/* The scan nodes of a kept plan's generic plan, in plan order. */
char *
modb_describe_access(SPIPlanPtr plan)
{
	CachedPlan *cached = SPI_plan_get_cached_plan(plan);
	StringInfoData text;
	ListCell   *cell;

	initStringInfo(&text);
	if (cached == NULL)
		return "unknown";
	foreach(cell, cached->stmt_list)
	{
		PlannedStmt *stmt = lfirst_node(PlannedStmt, cell);

		describe_node(stmt->planTree, stmt->rtable, &text);
	}
	ReleaseCachedPlan(cached, CurrentResourceOwner);
	return text.data;
}
