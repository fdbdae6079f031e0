/*
 * The modb shared library: its magic block, and _PG_init, which defines the session knobs (settings.c)
 * when the library is loaded (session_preload_libraries, or the first call of one of its functions) and,
 * when it is loaded at server start (shared_preload_libraries), asks for the shared block directory's
 * registry (shared_directory.c) and the shared match plans (shared_plans.c).
 */
#include "postgres.h"

#include "fmgr.h"
#include "miscadmin.h"
#include "storage/ipc.h"
#include "storage/lwlock.h"
#include "storage/shmem.h"
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

static shmem_request_hook_type previous_request;
static shmem_startup_hook_type previous_startup;

void
modb_shared_request(const char *name, Size size)
{
	RequestAddinShmemSpace(MAXALIGN(size));
	RequestNamedLWLockTranche(name, 1);
}

void *
modb_shared_struct(const char *name, Size size)
{
	bool		found;
	void	   *shared;

	LWLockAcquire(AddinShmemInitLock, LW_EXCLUSIVE);
	shared = ShmemInitStruct(name, size, &found);
	if (!found)
	{
		memset(shared, 0, size);
		*(LWLock **) shared = &(GetNamedLWLockTranche(name))->lock;
	}
	LWLockRelease(AddinShmemInitLock);
	return shared;
}

static void
request_shared(void)
{
	if (previous_request)
		previous_request();
	modb_shared_directory_request();
	modb_shared_plans_request();
}

static void
start_shared(void)
{
	if (previous_startup)
		previous_startup();
	modb_shared_directory_start();
	modb_shared_plans_start();
}

void
_PG_init(void)
{
	modb_define_settings();
	if (!process_shared_preload_libraries_in_progress)
		return;
	previous_request = shmem_request_hook;
	shmem_request_hook = request_shared;
	previous_startup = shmem_startup_hook;
	shmem_startup_hook = start_shared;
}
