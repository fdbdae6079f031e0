/*
 * The modb shared library: its magic block, and _PG_init, which defines the session knobs (settings.c)
 * when the library is loaded (session_preload_libraries, or the first call of one of its functions) and,
 * when it is loaded at server start (shared_preload_libraries), asks for the shared block directory's
 * registry (shared_directory.c) and the shared match plans (shared_plans.c).
 */
#include "postgres.h"

#include "fmgr.h"
#include "utils/builtins.h"

#include "modb.h"
#include "shared_directory.h"
#include "shared_plans.h"

PG_MODULE_MAGIC;

void		_PG_init(void);

PG_FUNCTION_INFO_V1(modb_library_version);

/* modb.library_version(): the extension version this library was built for (modb.control's). */
Datum
modb_library_version(PG_FUNCTION_ARGS)
{
	PG_RETURN_TEXT_P(cstring_to_text(MODB_LIBRARY_VERSION));
}

void
_PG_init(void)
{
	modb_define_settings();
	modb_shared_directory_init();
	modb_shared_plans_init();
}
