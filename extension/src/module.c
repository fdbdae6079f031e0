/*
 * The modb shared library's magic block: PostgreSQL checks it once per library, whatever C file is first
 * loaded. modb is SQL and PL/Python except for three C files: session_settings.c (the session's modb.*
 * settings, which no SQL view lists), continuity.c (the continuity ratio, ~100x faster than SQL) and
 * cube_gist.c (a GiST penalty and split for the 49-dimension feature cube).
 */
#include "postgres.h"

#include "fmgr.h"

PG_MODULE_MAGIC;
