/*
 * What a selection reports of itself (modb_select's stats, selection.c), for modb.explain_selection
 * (selection_explain.c) to show.
 */
#ifndef SELECTION_STATS_H
#define SELECTION_STATS_H

/* The kinds of a continuity term (term_codes.h), in the order a joint's components are coded. */
#define N_TERM_KINDS 4
#define TERM_KIND_NAMES {"position", "rotation", "velocity", "angular velocity"}

typedef struct BlockStats
{
	bool		read_directory;	/* this call read the block directory (a new generation of blocks) */
	bool		shared_directory;	/* the directory used is the server's shared one, not the session's copy */
	int64		blocks;			/* blocks in the directory */
	int64		supers_met;		/* super blocks (of 32 blocks) whose feature bounds met the box */
	int64		blocks_met;		/* blocks of those whose feature bounds met the box */
	int64		blocks_read;	/* of those: read, in the order of the least key their snippets can have */
	int64		blocks_rejected[N_TERM_KINDS];	/* of those: by a term their term bounds put out of range */
	int64		in_codes;		/* snippets whose feature codes met the box */
	int64		candidates_rejected[N_TERM_KINDS];	/* of those: by a term their term codes put out of range */
	double		ms;				/* the search's time (the directory's reading included) */
} BlockStats;

#define N_LEVELS 4				/* box levels 0-3; level 4 (the nearest start, any ratio) is the reference's */

typedef struct LevelStats
{
	bool		ran;
	bool		stored;			/* level 0 from the graph's stored transitions, not a box */
	char	   *box;			/* the box, as a cube literal */
	char	   *access;			/* how the rows were read (the kept plan's scan nodes) */
	BlockStats	blocks;
	int64		candidates;		/* the blocks' candidates (or the stored transitions) */
	int64		outside;		/* of those: not in the graph or collection named, passed over unread */
	int64		scanned;		/* of those: rows read (in the order of the least key they can have, until
								 * none left can make the answer) */
	int64		in_box;			/* of those: in the box (exactly) */
	int64		filtered;		/* of those: same pose and rate, in the collection, not excluded */
	int64		within;			/* of those: with a continuity ratio in the level's range */
	int64		returned;
	double		ms;
} LevelStats;

typedef struct SelectionStats
{
	const struct MatchPlan *plan;	/* selection.h */
	double		plan_ms;
	const char *reference_reason;	/* NULL: answered by the fast path */
	LevelStats	levels[N_LEVELS];
	int64		returned;
	double		total_ms;
} SelectionStats;

#endif							/* SELECTION_STATS_H */
