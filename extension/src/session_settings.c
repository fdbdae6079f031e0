/*
 * Misspelt session knobs. SET modb.<anything> = ... is accepted by PostgreSQL as a "placeholder" that no
 * SQL view lists (pg_settings hides placeholders), so an unknown knob would be silently ignored; this
 * function finds them for modb.match_plan(), which raises an error naming them.
 */
#include "postgres.h"

#include "catalog/pg_type.h"
#include "fmgr.h"
#include "utils/array.h"
#include "utils/builtins.h"
#include "utils/guc.h"
#include "utils/guc_tables.h"

PG_FUNCTION_INFO_V1(modb_session_settings);

/* Names of this session's modb.* settings that have a value (knobs and misspellings alike). */
Datum
modb_session_settings(PG_FUNCTION_ARGS)
{
	struct config_generic **vars = get_guc_variables();
	int			n = GetNumConfigOptions();
	Datum	   *names = palloc(sizeof(Datum) * Max(n, 1));
	int			k = 0;

	for (int i = 0; i < n; i++)
	{
		struct config_generic *var = vars[i];

		if (strncmp(var->name, "modb.", 5) == 0 && var->vartype == PGC_STRING)
		{
			char	   *value = *((struct config_string *) var)->variable;

			if (value != NULL && value[0] != '\0')
				names[k++] = CStringGetTextDatum(var->name);
		}
	}
	PG_RETURN_ARRAYTYPE_P(construct_array(names, k, TEXTOID, -1, false, TYPALIGN_INT));
}
