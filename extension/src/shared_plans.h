/*
 * Resolved match plans shared by every session of the server (shared_plans.c), where modb.so is preloaded
 * (shared_preload_libraries); elsewhere nothing is found and nothing shared.
 */
#ifndef SHARED_PLANS_H
#define SHARED_PLANS_H

#include "selection.h"

/* module.c's shared memory hooks, where the library is preloaded: the plans asked for, then set up. */
extern void modb_shared_plans_request(void);
extern void modb_shared_plans_start(void);
/* The plan shared under key in this database, into plan (its strings allocated in context); false: none. */
extern bool modb_shared_plan_find(const char *key, MatchPlan *plan, MemoryContext context);
/* Shares a plan resolved here under key, where this transaction has written nothing. */
extern void modb_shared_plan_share(const char *key, const MatchPlan *plan);

#endif							/* SHARED_PLANS_H */
