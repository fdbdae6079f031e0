/*
 * modb's session knobs (SET modb.<knob> = ...): declared as real settings, and the modb. prefix reserved,
 * so a misspelt knob is an error instead of a silently ignored placeholder. PostgreSQL lists no
 * placeholders in pg_settings, which is why this needs C; everything else in modb is SQL and PL/Python.
 */
#include "postgres.h"

#include "catalog/pg_type.h"
#include "fmgr.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/guc.h"
#include "utils/guc_tables.h"
#include "utils/memutils.h"

PG_MODULE_MAGIC;

/* Keep in step with modb.match_knobs() (tests/sql checks that they agree). */
static const char *const knob_names[] = {
	"joints", "norm", "position_threshold", "angle_threshold", "velocity_threshold",
	"angular_velocity_threshold", "velocity_terms", "heading_weight"};
#define N_KNOBS (sizeof(knob_names) / sizeof(knob_names[0]))

static char *knob_values[N_KNOBS];
static List *unknown_at_load = NIL;	/* placeholders the reservation removed, reported once */

void		_PG_init(void);

static bool
is_knob(const char *name)
{
	for (size_t i = 0; i < N_KNOBS; i++)
		if (strcmp(name, knob_names[i]) == 0)
			return true;
	return false;
}

/* Names of modb.* placeholders with a value that are not knobs. */
static List *
unknown_placeholders(MemoryContext context)
{
	struct config_generic **vars = get_guc_variables();
	int			n = GetNumConfigOptions();
	List	   *found = NIL;

	for (int i = 0; i < n; i++)
	{
		struct config_generic *var = vars[i];

		if ((var->flags & GUC_CUSTOM_PLACEHOLDER) && strncmp(var->name, "modb.", 5) == 0 &&
			!is_knob(var->name + 5) && var->vartype == PGC_STRING)
		{
			char	   *value = *((struct config_string *) var)->variable;

			if (value != NULL && value[0] != '\0')
				found = lappend(found, MemoryContextStrdup(context, var->name));
		}
	}
	return found;
}

void
_PG_init(void)
{
	MemoryContext old = MemoryContextSwitchTo(TopMemoryContext);

	unknown_at_load = unknown_placeholders(TopMemoryContext);
	MemoryContextSwitchTo(old);
	for (size_t i = 0; i < N_KNOBS; i++)
		DefineCustomStringVariable(psprintf("modb.%s", knob_names[i]),
								   "Overrides this setting of select_next_snippet's match profile (modb.match_knobs()).",
								   "Empty: the profile's value.",
								   &knob_values[i], "", PGC_USERSET, 0, NULL, NULL, NULL);
	MarkGUCPrefixReserved("modb");
}

PG_FUNCTION_INFO_V1(modb_unknown_settings);

/* Misspelt modb.* settings of this session, each reported once. */
Datum
modb_unknown_settings(PG_FUNCTION_ARGS)
{
	List	   *names = list_concat(unknown_placeholders(CurrentMemoryContext), unknown_at_load);
	Datum	   *elems = palloc(sizeof(Datum) * Max(list_length(names), 1));
	int			k = 0;
	ListCell   *cell;

	foreach(cell, names)
		elems[k++] = CStringGetTextDatum((char *) lfirst(cell));
	unknown_at_load = NIL;		/* the list cells stay in TopMemoryContext: a few bytes, once */
	PG_RETURN_ARRAYTYPE_P(construct_array(elems, k, TEXTOID, -1, false, TYPALIGN_INT));
}
