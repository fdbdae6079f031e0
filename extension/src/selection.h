/*
 * The fast path of select_next_snippets (selection.c), the match plan it runs with (selection_plan.c) and
 * the box search over snippet blocks (snippet_blocks.c, block_directory.c). What a call reports of itself
 * is in selection_stats.h; modb.explain_selection (selection_explain.c) runs it and shows that.
 */
#ifndef SELECTION_H
#define SELECTION_H

#include "executor/spi.h"
#include "portability/instr_time.h"

#include "kept_plans.h"
#include "modb.h"
#include "selection_stats.h"

/* A match profile resolved with the session's knobs (modb.match_plan), as the fast path needs it. */
typedef struct MatchPlan
{
	Thresholds	thresholds;
	double		box_half_width[N_FEATURES];
	double		heading_weight;
	double		continuity_weight;
	bool		has_lookahead;
	double		lookahead;
	bool		has_graph;
	int64		graph_id;
	bool		graph_lookahead;
	bool		stored_key;		/* the graph's stored transitions were built for these thresholds */
	bool		has_grid;		/* rank level 0 by the graph's cost-to-go */
	CostGrid	grid;
	char	   *annotations;	/* the annotation names candidates keep to, a text[] literal; NULL: none */
	char	   *shown;			/* the plan as jsonb text, for explain_selection */
	bool		cached;			/* taken from this session's cache, not resolved now */
	bool		shared;			/* taken from the server's shared plans (then cached) */
} MatchPlan;

/*
 * The plan for `profile` (NULL: default) with this session's knobs, at this generation of the profiles and
 * graphs (modb.generations 'match_plans'), of the extension's version whose blocks are blocks_relid: this
 * session's, else the server's shared one (shared_plans.c), else resolved now; must be called inside SPI.
 */
extern const MatchPlan *modb_match_plan(text *profile, int64 generation, Oid blocks_relid,
										 const char *extension_version);

/* snippet_blocks.c and block_directory.c: the box search over blocks of consecutive snippets. */
#define BLOCK_SNIPPETS 32

/* A block's clip source (its snippets' clip version, side, pose, rate and collection). */
typedef struct BlockSource
{
	int64		clip_id;
	int32		version;
	bool		mirrored;
	char	   *pose_key;
	double		fps;
	int64		collection_id;
} BlockSource;

/*
 * What the objective of a snippet is computed from, kept in its block (as float4) beside its code so that
 * candidates can be read in the order of the least objective they can have: net_translation (3),
 * future_translation (3) and future_heading; NaN for NULL.
 */
#define N_OBJECTIVE_INPUTS 7

/*
 * modb.rest_speed() and modb.walk_speed() (89_synthesis.sql, m/s), by which a block's end bounds sort its
 * snippets (a search uses them only where those functions return these): end_bounds holds the {x, z}
 * bounds of the net translations of the snippets that end standing (x low, z low, x high, z high; NaN:
 * none), then of those that end walking, so that coming to rest and setting off pass over a block that
 * has none without reading it, and rank the others by the snippets that can answer (0.29.0).
 */
#define BLOCK_REST_SPEED 0.1
#define BLOCK_WALK_SPEED 0.5
#define N_END_BOUNDS 8

/* Which of a box's blocks a search keeps: all, or those that may hold a snippet ending standing or walking. */
typedef enum BlockEnds
{
	BLOCK_ENDS_ANY,
	BLOCK_ENDS_STANDING,
	BLOCK_ENDS_WALKING
} BlockEnds;

typedef struct BlockCandidate
{
	int64		id;
	bool		hinted;			/* in exactly one block, which holds its objective's inputs */
	double		inputs[N_OBJECTIVE_INPUTS];
	double		least_ratio;	/* the least continuity ratio its block's term codes allow (0: unknown) */
	float		end_speed;		/* its pelvis' ground speed at its end, as its block holds it (NaN: unknown) */
} BlockCandidate;

extern int	modb_block_code(double x, float low, float high);
extern void modb_store_block(const int64 *ids, const double (*x)[N_FEATURES],
							 const double (*inputs)[N_OBJECTIVE_INPUTS], const Terminator *begins,
							 const double *end_speeds, int n, const BlockSource *s, int pack_order);
/*
 * A snippet's id (column 1), begin features (column `features`), objective inputs (the three after),
 * begin terminator (the four after those) and end speed (the one after).
 */
extern void modb_block_row(HeapTuple row, TupleDesc desc, int features, int64 *id, double *x, double *inputs,
						   Terminator *begin, double *end_speed);
/*
 * The columns (terminators joined as b at the begin, e at the end) that modb_block_row's rows end with: the
 * begin terminator and the end speed, computed as coming to rest computes it (89_synthesis.sql).
 */
#define BEGIN_TERMINATOR_COLUMNS \
	"b.positions, b.rotations, b.velocities, b.angular_velocities, sqrt(e.velocities[1] ^ 2 + e.velocities[3] ^ 2)"
#define BLOCK_ROW_JOINS \
	" JOIN modb.terminators b ON b.id = s.begin_terminator JOIN modb.terminators e ON e.id = s.end_terminator"
struct TermTest;					/* term_codes.h */

/*
 * A box search over the blocks (block_directory.c): the blocks of the pose and rate (pose_key NULL: of
 * every one, for a start) whose bounds meet the
 * box and whose term bounds the directory cannot reject (`test`: NULL, none) and that may hold a snippet
 * that ends as `ends` asks, each with the least key its snippets can have, which `bound` computes from the
 * bounds of their objective inputs (of those ending as asked, where the block holds them; -Infinity where
 * one is not known); a block is read when the caller asks, for its candidates.
 */
typedef struct BlockSearch BlockSearch;
typedef double (*BlockBound) (const float *inputs_lo, const float *inputs_hi, void *arg);

extern BlockSearch *modb_block_search(Oid relid, int64 generation, const char *pose_key, double fps,
									  const double *lo, const double *hi, const struct TermTest *test,
									  BlockEnds ends, BlockBound bound, void *arg, BlockStats *stats);
extern int	modb_block_search_count(const BlockSearch *search);
extern double modb_block_search_bound(const BlockSearch *search, int i);
/* Reads block i: its snippets in the box that its term codes do not reject, into out (BLOCK_SNIPPETS long). */
extern int	modb_block_search_read(BlockSearch *search, int i, BlockCandidate *out);
/* Candidates whose end speed `keep` refuses are passed over before their term test. */
typedef bool (*BlockKeep) (float end_speed, const void *arg);
extern void modb_block_search_keep(BlockSearch *search, BlockKeep keep, const void *arg);
extern void modb_block_search_end(BlockSearch *search);

/* Runs a selection into `store` (rows of select_next_snippets' result type); stats may be NULL. */
extern void modb_select(FunctionCallInfo fcinfo, Tuplestorestate *store, TupleDesc desc, SelectionStats *stats);

/* The snippets of a graph or a collection (candidate_sets.c); NULL where there are too many to keep. */
typedef struct MemberSet MemberSet;
extern const MemberSet *modb_graph_members(int64 graph_id, int64 plans_generation, int64 blocks_generation);
extern const MemberSet *modb_collection_members(const int64 *collections, int n_collections,
												int64 blocks_generation);
extern bool modb_members_hold(const MemberSet *s, int64 id);

#endif							/* SELECTION_H */
