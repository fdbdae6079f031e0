/*
 * The session knobs, SET modb.<knob>, as real settings: pg_settings lists them with a description and unit,
 * a bad value is refused at SET (check hooks below, the same ranges match_plan checks a profile's values
 * against), and once the library is loaded an unknown modb.<name> is refused too (MarkGUCPrefixReserved).
 * Each knob is a string so that it can also say '' (the default) or "profile": use the profile's value.
 */
#include "postgres.h"

#include <ctype.h>
#include <math.h>

#include "utils/builtins.h"
#include "utils/memutils.h"
#include "utils/guc.h"

#include "modb.h"

typedef enum KnobKind
{
	KNOB_JOINTS,
	KNOB_NORM,
	KNOB_THRESHOLD,				/* positive: 1e-300 to 1e300 */
	KNOB_WEIGHT,				/* 0, or 1e-300 to 1e300 */
	KNOB_DISTANCE,				/* positive, like a threshold */
	KNOB_BOOLEAN,
	KNOB_NAME,
	KNOB_ANNOTATIONS			/* names, comma-separated, ! before one to exclude it */
} KnobKind;

typedef struct Knob
{
	const char *name;			/* without "modb." */
	KnobKind	kind;
	const char *unit;
	const char *description;
} Knob;

/* In modb.match_knobs() order (79_match_plan.sql): the order of modb_knob_values(). */
static const Knob knobs[N_KNOBS] = {
	{"joints", KNOB_JOINTS, NULL, "Standard joints compared at a seam, comma-separated (modb.standard_joints())"},
	{"norm", KNOB_NORM, NULL, "How joint positions are compared at a seam: l1 or l2"},
	{"position_threshold", KNOB_THRESHOLD, "metres", "Largest joint position difference at a seam, every compared joint"},
	{"angle_threshold", KNOB_THRESHOLD, "radians", "Largest joint rotation difference at a seam, every compared joint"},
	{"velocity_threshold", KNOB_THRESHOLD, "m/s", "Largest joint velocity difference at a seam, every compared joint"},
	{"angular_velocity_threshold", KNOB_THRESHOLD, "rad/s",
	"Largest joint angular velocity difference at a seam, every compared joint"},
	{"velocity_terms", KNOB_BOOLEAN, NULL, "Whether seams compare velocities and angular velocities (on or off)"},
	{"heading_weight", KNOB_WEIGHT, "metres per radian", "Weight of the heading term of the objective"},
	{"continuity_weight", KNOB_WEIGHT, "metres per unit of continuity ratio",
	"Weight of the continuity ratio in the objective: the smoother candidate wins unless another leads clearly better"},
	{"lookahead_distance", KNOB_DISTANCE, "metres", "A farther goal is scored as the point this far along the way to it"},
	{"graph", KNOB_NAME, NULL, "Transition graph (modb.graphs name) whose snippets the selection chooses among; none: no graph, not even synthesis's default one"},
	{"graph_lookahead", KNOB_BOOLEAN, NULL,
	"Graphs without a cost-to-go: score a candidate also by its best successor (on or off)"},
	{"graph_cost_to_go", KNOB_BOOLEAN, NULL, "With a graph that has one, rank level 0 by its cost-to-go (on or off)"},
	{"annotations", KNOB_ANNOTATIONS, NULL,
	"Annotation names, comma-separated (! before one excludes it): candidates lie wholly in segments with one of the names, and in none with an excluded one"},
};

static char *values[N_KNOBS];

/* '' or "profile": the profile's value. */
bool
modb_knob_is_profile(const char *value)
{
	return value == NULL || value[0] == '\0' || pg_strcasecmp(value, "profile") == 0;
}

const char *
modb_knob_value(int knob)
{
	return values[knob];
}

const char *
modb_knob_name(int knob)
{
	return knobs[knob].name;
}

/* A decimal number as match_plan reads one: digits, one point, an exponent; no NaN, Infinity or hex. */
static bool
parse_decimal(const char *text, double *result)
{
	const char *p = text;
	char	   *end;
	bool		digits = false;

	while (isspace((unsigned char) *p))
		p++;
	if (*p == '+' || *p == '-')
		p++;
	for (const char *q = p; *q && !isspace((unsigned char) *q); q++)
	{
		if (isdigit((unsigned char) *q))
			digits = true;
		else if (!strchr(".eE+-", *q))
			return false;
	}
	if (!digits)
		return false;
	errno = 0;
	*result = strtod(text, &end);
	while (isspace((unsigned char) *end))
		end++;
	return *end == '\0' && end != text && isfinite(*result);
}

static bool
check_number(const Knob *knob, const char *value)
{
	double		x;
	bool		positive = knob->kind != KNOB_WEIGHT;

	if (parse_decimal(value, &x) && ((x == 0 && !positive) || (x >= 1e-300 && x <= 1e300)))
		return true;
	GUC_check_errdetail("%s %s (allowed: %s1e-300 to 1e300 %s).",
						knob->kind == KNOB_THRESHOLD ? "Thresholds must be" : psprintf("modb.%s must", knob->name),
						knob->kind == KNOB_THRESHOLD ? "positive and finite"
						: positive ? "be positive and finite" : "not be negative and must be finite",
						positive ? "" : "0, or ", knob->unit);
	return false;
}

static bool
check_joints(const char *value)
{
	static const char *const names[N_JOINTS] = STANDARD_JOINT_NAMES;
	char	   *list = pstrdup(value);
	char	   *saveptr = NULL;
	int			n = 0;

	for (char *item = strtok_r(list, ",", &saveptr); item; item = strtok_r(NULL, ",", &saveptr))
	{
		char	   *name = item;
		char	   *last;
		bool		known = false;

		while (isspace((unsigned char) *name))
			name++;
		last = name + strlen(name);
		while (last > name && isspace((unsigned char) last[-1]))
			*--last = '\0';
		for (int j = 0; j < N_JOINTS; j++)
			known = known || strcmp(name, names[j]) == 0;
		if (!known)
		{
			GUC_check_errdetail("\"%s\" is not a standard joint.", name);
			GUC_check_errhint("Standard joints: modb.standard_joints().");
			return false;
		}
		n++;
	}
	if (n == 0)
	{
		GUC_check_errdetail("Name at least one standard joint.");
		return false;
	}
	return true;
}

static bool
check_knob(const Knob *knob, const char *value)
{
	bool		ok;

	if (modb_knob_is_profile(value))
		return true;
	GUC_check_errhint("SET modb.%s to an allowed value, or to profile (or RESET modb.%s) for the profile's.",
					  knob->name, knob->name);
	switch (knob->kind)
	{
		case KNOB_JOINTS:
			return check_joints(value);
		case KNOB_NORM:
			ok = pg_strcasecmp(value, "l1") == 0 || pg_strcasecmp(value, "l2") == 0;
			if (!ok)
				GUC_check_errdetail("modb.norm must be l1 or l2.");
			return ok;
		case KNOB_BOOLEAN:
			ok = parse_bool(value, NULL);
			if (!ok)
				GUC_check_errdetail("modb.%s must be on or off.", knob->name);
			return ok;
		case KNOB_NAME:
			return true;
		case KNOB_ANNOTATIONS:
			for (const char *c = value; *c; c++)
				if (*c == ':' || iscntrl((unsigned char) *c))
				{
					GUC_check_errdetail("modb.annotations is a list of names separated by commas, without ':' or control characters.");
					return false;
				}
			return true;
		default:
			return check_number(knob, value);
	}
}

/* A check hook is not told which setting it checks: one per knob. */
#define KNOB_HOOK(i) \
	static bool check_knob_##i(char **newval, void **extra, GucSource source) \
	{ \
		return check_knob(&knobs[i], *newval); \
	}
KNOB_HOOK(0) KNOB_HOOK(1) KNOB_HOOK(2) KNOB_HOOK(3) KNOB_HOOK(4) KNOB_HOOK(5) KNOB_HOOK(6)
KNOB_HOOK(7) KNOB_HOOK(8) KNOB_HOOK(9) KNOB_HOOK(10) KNOB_HOOK(11) KNOB_HOOK(12) KNOB_HOOK(13)

static GucStringCheckHook hooks[N_KNOBS] = {
	check_knob_0, check_knob_1, check_knob_2, check_knob_3, check_knob_4, check_knob_5, check_knob_6,
	check_knob_7, check_knob_8, check_knob_9, check_knob_10, check_knob_11, check_knob_12, check_knob_13,
};

/* modb.foot_hold: read by synthesis from models (the kernel's foot_hold), not a match knob. */
static bool foot_hold = true;

/* Called from _PG_init: defines the knobs and reserves the prefix (earlier placeholders are checked then). */
void
modb_define_settings(void)
{
	MemoryContext old = MemoryContextSwitchTo(TopMemoryContext);	/* the descriptions are not copied */

	DefineCustomBoolVariable("modb.foot_hold",
							 "Synthesis from models holds each stance foot where it touched down, at its source's height.",
							 "modb.synthesize_from_models reads it (docs/synthesis.md \"Feet on the ground\"); off shows "
							 "the seams' treatment alone, for comparison.",
							 &foot_hold, true, PGC_USERSET, 0, NULL, NULL, NULL);

	for (int i = 0; i < N_KNOBS; i++)
	{
		const Knob *knob = &knobs[i];

		DefineCustomStringVariable(psprintf("modb.%s", knob->name),
								   knob->unit ? psprintf("%s (%s); empty or profile: the match profile's.",
														 knob->description, knob->unit)
								   : psprintf("%s; empty or profile: the match profile's.", knob->description),
								   "Overrides the match profile's value for select_next_snippet in this session "
								   "(docs/reference.md \"Knobs\"). Empty by default (an earlier version's match_plan reads it so too).",
								   &values[i], "", PGC_USERSET, 0, hooks[i], NULL, NULL);
	}
	MemoryContextSwitchTo(old);
	MarkGUCPrefixReserved("modb");
}
