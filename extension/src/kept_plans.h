/*
 * Kept SPI plans (kept_plans.c): planned once per session, and how each reads its rows. Shared by the
 * selection, its match plan, block packing and explain_selection, and depending on none of them.
 */
#ifndef KEPT_PLANS_H
#define KEPT_PLANS_H

#include "executor/spi.h"

/* A kept, generic SPI plan of a query (planned once per session, never JIT-compiled: selection.c). */
extern SPIPlanPtr modb_kept_plan(SPIPlanPtr *slot, const char *query, int nargs, Oid *argtypes);

/* The scan nodes of a kept plan's generic plan, in plan order (what explain_selection shows). */
extern char *modb_describe_access(SPIPlanPtr plan);

#endif							/* KEPT_PLANS_H */
