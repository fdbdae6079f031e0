/*
 * The modb shared library: its magic block, and _PG_init, which defines the session knobs (settings.c)
 * when the library is loaded (session_preload_libraries, or the first call of one of its functions).
 */
#include "postgres.h"

#include "fmgr.h"

#include "modb.h"

PG_MODULE_MAGIC;

void		_PG_init(void);

void
_PG_init(void)
{
	modb_define_settings();
}
