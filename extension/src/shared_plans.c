/*
 * Resolved match plans shared by every session of the server (0.29.0), where modb.so is in
 * shared_preload_libraries: resolving a profile with modb.match_plan costs a new session 7-9 ms (its
 * PL/pgSQL compiled and planned), most of a first call. A plan is shared under its session key
 * (selection_plan.c: the profile, the generation of profiles and graphs, the knobs), the database, the
 * relation of the blocks (a new one after the extension is dropped and created again, when generations
 * start again) and the extension's version, and only by a transaction that has written nothing (its
 * generation is then a committed one). With the library preloaded an unknown modb setting is refused at
 * SET, so a session cannot hold one that resolving would have refused.
 */
#include "postgres.h"

#include "access/xact.h"
#include "miscadmin.h"
#include "storage/lwlock.h"

#include "shared_plans.h"

#define SHARED_PLANS 64
#define KEY_BYTES 1024
#define TEXT_BYTES 7168			/* the plan as shown (jsonb text) and its annotations */

typedef struct SharedPlan
{
	Oid			database;		/* InvalidOid: free */
	uint64		used;
	char		key[KEY_BYTES];
	MatchPlan	plan;			/* shown and annotations point nowhere: they are in text */
	int			shown_length;
	int			annotations_length;	/* -1: none */
	char		text[TEXT_BYTES];
} SharedPlan;

typedef struct SharedPlans
{
	LWLock	   *lock;
	uint64		clock;
	SharedPlan	plans[SHARED_PLANS];
} SharedPlans;

#define PLANS "modb match plans"	/* the struct's name in shared memory, and its lock's */

static SharedPlans *shared;

void
modb_shared_plans_request(void)
{
	modb_shared_request(PLANS, sizeof(SharedPlans));
}

void
modb_shared_plans_start(void)
{
	shared = modb_shared_struct(PLANS, sizeof(SharedPlans));
}

bool
modb_shared_plan_find(const char *key, MatchPlan *plan, MemoryContext context)
{
	bool		found = false;

	if (shared == NULL || strlen(key) >= KEY_BYTES)
		return false;
	LWLockAcquire(shared->lock, LW_EXCLUSIVE);
	for (int i = 0; i < SHARED_PLANS && !found; i++)
	{
		SharedPlan *p = &shared->plans[i];

		if (p->database != MyDatabaseId || strcmp(p->key, key) != 0)
			continue;
		found = true;
		p->used = ++shared->clock;
		*plan = p->plan;
		plan->shown = MemoryContextAlloc(context, p->shown_length + 1);
		memcpy(plan->shown, p->text, p->shown_length + 1);
		plan->annotations = NULL;
		if (p->annotations_length >= 0)
		{
			plan->annotations = MemoryContextAlloc(context, p->annotations_length + 1);
			memcpy(plan->annotations, p->text + p->shown_length + 1, p->annotations_length + 1);
		}
	}
	LWLockRelease(shared->lock);
	return found;
}

void
modb_shared_plan_share(const char *key, const MatchPlan *plan)
{
	int			shown_length = strlen(plan->shown);
	int			annotations_length = plan->annotations ? strlen(plan->annotations) : -1;
	SharedPlan *p;

	if (shared == NULL || GetTopTransactionIdIfAny() != InvalidTransactionId || strlen(key) >= KEY_BYTES
		|| shown_length + 1 + Max(annotations_length, 0) + 1 > TEXT_BYTES)
		return;
	LWLockAcquire(shared->lock, LW_EXCLUSIVE);
	/* the same key again (two sessions resolved it at once), else a free entry, else the least used */
	p = &shared->plans[0];
	for (int i = 0; i < SHARED_PLANS; i++)
	{
		SharedPlan *q = &shared->plans[i];

		if (q->database == MyDatabaseId && strcmp(q->key, key) == 0)
		{
			p = q;
			break;
		}
		if (p->database != InvalidOid && (q->database == InvalidOid || q->used < p->used))
			p = q;
	}
	p->database = MyDatabaseId;
	p->used = ++shared->clock;
	strcpy(p->key, key);
	p->plan = *plan;
	p->plan.shown = p->plan.annotations = NULL;
	p->shown_length = shown_length;
	p->annotations_length = annotations_length;
	memcpy(p->text, plan->shown, shown_length + 1);
	if (annotations_length >= 0)
		memcpy(p->text + shown_length + 1, plan->annotations, annotations_length + 1);
	LWLockRelease(shared->lock);
}
