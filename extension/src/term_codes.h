/*
 * Term codes (term_codes.c): every term of the continuity ratio, bounded where the box search reads. A
 * snippet block keeps, for its snippets' begin terminators, the bounds of each term component (16-bit on a
 * fixed scale per kind) and each snippet's 4-bit code within them; a request turns them into lower bounds
 * of each term, so a block or a candidate whose ratio cannot be within the level is rejected without
 * reading its rows. Conservative by construction: a bound never exceeds what continuity.c computes.
 */
#ifndef TERM_CODES_H
#define TERM_CODES_H

#include "modb.h"
#include "selection_stats.h"

/* Per joint: position xyz, rotation xyz (of the representative with w >= 0), velocity xyz, angular velocity xyz. */
#define TERM_KIND_COMPONENTS 3
#define TERM_JOINT_COMPONENTS (N_TERM_KINDS * TERM_KIND_COMPONENTS)
#define TERM_COMPONENTS (N_JOINTS * TERM_JOINT_COMPONENTS)
#define TERM_BOUNDS_BYTES (TERM_COMPONENTS * 2 * 2)	/* uint16 low codes, then high codes */
#define TERM_CODE_BYTES ((TERM_COMPONENTS + 1) / 2)	/* two 4-bit codes a byte */

/* A terminator's term components in their coded order (rotations with w >= 0); each w into w[joint]. */
extern bool modb_term_components(const Terminator *t, double *components, double *w);

/* A block's term bounds and its snippets' codes, from their begin terminators (the writer's side). */
extern void modb_term_encode(const Terminator *snippets, int n, uint8 *bounds, uint8 *codes);

/* One level of a request: its end terminator and each term's limit (threshold x the level's scale). */
typedef struct TermTest
{
	int			n_terms;
	int16		joint[N_JOINTS * N_TERM_KINDS];
	int8		kind[N_JOINTS * N_TERM_KINDS];
	double		limit_sq[N_JOINTS * N_TERM_KINDS];	/* a squared distance (a chord for rotations) above it rejects */
	double		ratio_factor[N_JOINTS * N_TERM_KINDS];	/* term ratio^2 >= least square x this */
	double		query[TERM_COMPONENTS + N_JOINTS];	/* the end's components; each rotation's w after them */
} TermTest;

/* The test of `end` at a level whose ratio must be <= high, under thresholds t; false: nothing can reject. */
extern bool modb_term_test(TermTest *test, const Terminator *end, const Thresholds *t, double high);

/* A block's decoded bounds, for its snippets' tests. */
typedef struct TermBlock
{
	double		low[TERM_COMPONENTS];
	double		step[TERM_COMPONENTS];	/* of a 4-bit code; 0: the component is unbounded in this block */
	double		high[TERM_COMPONENTS];
	const uint8 *codes;
	/* After its first snippet within every term: the terms that every snippet of the block is within
	 * (none can reject one) are left out of its later snippets' tests; their least over the block
	 * still bounds the ratio. */
	bool		split;
	int			n_tested;
	int16		tested[N_JOINTS * N_TERM_KINDS];	/* the test's terms a snippet's codes are tested on */
	double		untested_sq;	/* the largest least square x ratio factor of the others over the block */
} TermBlock;

/*
 * Decodes a block's bounds and tests them: the kind of the first term that rejects every snippet of the
 * block, or -1. `bytes` is TERM_BOUNDS_BYTES long.
 */
extern int	modb_term_block(const TermTest *test, const uint8 *bytes, const uint8 *codes, TermBlock *block);

/*
 * Tests snippet i of a block: the kind of the first term that rejects it, or -1 and the least continuity
 * ratio its codes allow (a lower bound, for the order candidates are read in).
 */
extern int	modb_term_snippet(const TermTest *test, TermBlock *block, int i, double *least_ratio);

#endif							/* TERM_CODES_H */
