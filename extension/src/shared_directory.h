/*
 * The block directory shared by every session of the server (shared_directory.c): the registry exists
 * only where modb.so is in shared_preload_libraries; elsewhere each function says so (NULL, false).
 */
#ifndef SHARED_DIRECTORY_H
#define SHARED_DIRECTORY_H

/* module.c's shared memory hooks, where the library is preloaded: the registry asked for, then set up. */
extern void modb_shared_directory_request(void);
extern void modb_shared_directory_start(void);
extern bool modb_shared_directory_available(void);
/* The shared image of modb.snippet_blocks (relid, relfilenode) at this generation, mapped; NULL: none. */
extern const void *modb_shared_directory_attach(Oid relid, Oid relfilenode, int64 generation);
/*
 * Shares an image this session built (copies its size bytes) where no newer one is shared, and maps it;
 * NULL where nothing can be shared (no registry, a transaction that wrote, no segment to be had).
 */
extern const void *modb_shared_directory_publish(const void *image, Size size, Oid relid, Oid relfilenode,
												 int64 generation);
/* Lets go of the image this session maps. */
extern void modb_shared_directory_release(void);

#endif							/* SHARED_DIRECTORY_H */
