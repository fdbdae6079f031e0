/*
 * The block directory shared by every session of the server (0.29.0): where modb.so is in
 * shared_preload_libraries, a small registry in shared memory names, per database, the dynamic shared
 * memory segment that holds the newest directory image a session built (block_directory.c), with the
 * relation and generation of modb.snippet_blocks it is valid for. A session whose call reads that
 * generation maps the segment (a few pages touched, no index read, no copy) instead of reading its own;
 * one that reads another generation builds its own image and, if it is newer and this transaction has
 * written nothing (so the generation is committed and names exactly these blocks for every snapshot that
 * reads it), shares it, unpinning the one it replaces, which goes when its last session lets go of it.
 * Without the preload (session_preload_libraries, or a first call) there is no registry: every session
 * keeps its own copy, as before 0.29.0.
 */
#include "postgres.h"

#include "access/xact.h"
#include "miscadmin.h"
#include "storage/dsm.h"
#include "storage/lwlock.h"

#include "modb.h"
#include "shared_directory.h"

#define SHARED_SLOTS 32			/* databases (and relations) whose directories are shared at once */

typedef struct SharedSlot
{
	Oid			database;		/* InvalidOid: free */
	Oid			relid;
	Oid			relfilenode;
	int64		generation;
	dsm_handle	handle;
	uint64		used;			/* the registry's clock when it was last shared or taken */
} SharedSlot;

typedef struct SharedRegistry
{
	LWLock	   *lock;
	uint64		clock;
	SharedSlot	slots[SHARED_SLOTS];
} SharedRegistry;

#define REGISTRY "modb block directories"	/* the struct's name in shared memory, and its lock's */

static SharedRegistry *registry;
static dsm_segment *attached;	/* the segment this session maps, if any */

void
modb_shared_directory_request(void)
{
	modb_shared_request(REGISTRY, sizeof(SharedRegistry));
}

void
modb_shared_directory_start(void)
{
	registry = modb_shared_struct(REGISTRY, sizeof(SharedRegistry));
}

bool
modb_shared_directory_available(void)
{
	return registry != NULL;
}

static SharedSlot *
slot_of(Oid relid)
{
	for (int i = 0; i < SHARED_SLOTS; i++)
		if (registry->slots[i].database == MyDatabaseId && registry->slots[i].relid == relid)
			return &registry->slots[i];
	return NULL;
}

/* Lets go of the segment this session maps (its image is no longer used). */
void
modb_shared_directory_release(void)
{
	if (attached != NULL)
		dsm_detach(attached);
	attached = NULL;
}

static const void *
keep_mapped(dsm_segment *segment)
{
	modb_shared_directory_release();
	dsm_pin_mapping(segment);	/* beyond this transaction: until the session lets go of it */
	attached = segment;
	return dsm_segment_address(segment);
}

const void *
modb_shared_directory_attach(Oid relid, Oid relfilenode, int64 generation)
{
	dsm_handle	handle = DSM_HANDLE_INVALID;
	SharedSlot *slot;
	dsm_segment *segment;

	if (registry == NULL)
		return NULL;
	LWLockAcquire(registry->lock, LW_EXCLUSIVE);
	slot = slot_of(relid);
	if (slot != NULL && slot->relfilenode == relfilenode && slot->generation == generation)
	{
		handle = slot->handle;
		slot->used = ++registry->clock;
	}
	LWLockRelease(registry->lock);
	if (handle == DSM_HANDLE_INVALID)
		return NULL;
	/* NULL when a newer image replaced it and its last session let go of it meanwhile */
	segment = dsm_attach(handle);
	return segment != NULL ? keep_mapped(segment) : NULL;
}

const void *
modb_shared_directory_publish(const void *image, Size size, Oid relid, Oid relfilenode, int64 generation)
{
	dsm_segment *segment;
	dsm_handle	replaced = DSM_HANDLE_INVALID;
	SharedSlot *slot;
	bool		shared = false;

	/* A transaction that wrote may see its own uncommitted blocks, under a number no one else will see. */
	if (registry == NULL || GetTopTransactionIdIfAny() != InvalidTransactionId)
		return NULL;
	segment = dsm_create(size, DSM_CREATE_NULL_IF_MAXSEGMENTS);
	if (segment == NULL)
		return NULL;
	memcpy(dsm_segment_address(segment), image, size);
	dsm_pin_segment(segment);
	LWLockAcquire(registry->lock, LW_EXCLUSIVE);
	slot = slot_of(relid);
	if (slot == NULL)
	{
		/* a free slot, else the one least recently used */
		slot = &registry->slots[0];
		for (int i = 1; i < SHARED_SLOTS && slot->database != InvalidOid; i++)
			if (registry->slots[i].database == InvalidOid || registry->slots[i].used < slot->used)
				slot = &registry->slots[i];
		replaced = slot->database != InvalidOid ? slot->handle : DSM_HANDLE_INVALID;
		slot->database = InvalidOid;
	}
	else if (slot->relfilenode != relfilenode || slot->generation < generation)
		replaced = slot->handle;
	else
		slot = NULL;			/* as new or newer is shared already */
	if (slot != NULL)
	{
		slot->database = MyDatabaseId;
		slot->relid = relid;
		slot->relfilenode = relfilenode;
		slot->generation = generation;
		slot->handle = dsm_segment_handle(segment);
		slot->used = ++registry->clock;
		shared = true;
	}
	LWLockRelease(registry->lock);
	if (replaced != DSM_HANDLE_INVALID)
		dsm_unpin_segment(replaced);	/* goes when the last session mapping it lets go */
	if (!shared)
		dsm_unpin_segment(dsm_segment_handle(segment));	/* this session's alone: goes with its mapping */
	return keep_mapped(segment);
}
