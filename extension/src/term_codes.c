/*
 * Term codes: lower bounds of every term of the continuity ratio (continuity.c) from what a snippet block
 * holds, so that the box search rejects a block or a candidate on any term without reading its rows.
 *
 * A block keeps each term component's bounds over its snippets as 16-bit codes on a fixed scale per kind
 * (code 0: unbounded below, 65535: unbounded above; one code of margin each side) and each snippet's 4-bit
 * code within them. A rotation is coded by the x, y, z of its representative with w >= 0 (q and -q are one
 * rotation); w follows from them for a unit quaternion, and a joint whose quaternions are not unit (within
 * 1e-5) is left unbounded in the block. A request bounds each term below: per component, the distance from
 * its own value to the snippet's interval; a rotation's smaller chord to +-q bounds its angle, since for
 * any a, b: angle = 4 atan2(min, max) with min^2 + max^2 = 2|a|^2 + 2|b|^2. Every comparison allows for the
 * float4 roundings of the rule's own arithmetic with a margin a thousand times larger, so a bound never
 * exceeds the term as continuity.c computes it: nothing the rule would return is rejected.
 */
#include "postgres.h"

#include <math.h>

#include "term_codes.h"

#define CODE_STEPS 65535
#define NIBBLE_STEPS 16
#define UNIT_SLACK 1e-5			/* |q|^2 within this of 1 */
#define LIMIT_SLACK 1e-5		/* relative: reject only above limit^2 x (1 + this) */
/*
 * A block is tested on the terms that rejected most in this session only (a candidate on all of them):
 * rejections concentrate on a few terms, and a block that passes would cost every term's test.
 */
#define BLOCK_TERMS 12

/* Each kind's fixed scale (a value outside it leaves the component unbounded). */
static const double kind_scale[N_TERM_KINDS][2] = {{-8, 8}, {-1.0001, 1.0001}, {-40, 40}, {-200, 200}};

/* How often each (joint, kind) term rejected, in this session: the order a test tries them in. */
static uint64 rejections[N_JOINTS * N_TERM_KINDS];

static inline int
kind_of_component(int c)
{
	return (c % TERM_JOINT_COMPONENTS) / TERM_KIND_COMPONENTS;
}

static inline double
scale_step(int kind)
{
	return (kind_scale[kind][1] - kind_scale[kind][0]) / CODE_STEPS;
}

bool
modb_term_components(const Terminator *t, double *out, double *w)
{
	bool		unit = true;

	for (int j = 0; j < N_JOINTS; j++)
	{
		double	   *c = out + j * TERM_JOINT_COMPONENTS;
		const float *q = t->rotations + 4 * j;
		double		sign = q[3] < 0 ? -1.0 : 1.0;
		double		norm2 = 0;

		for (int a = 0; a < 3; a++)
		{
			c[a] = t->positions[3 * j + a];
			c[3 + a] = sign * q[a];
			c[6 + a] = t->velocities[3 * j + a];
			c[9 + a] = t->angular_velocities[3 * j + a];
		}
		for (int a = 0; a < 4; a++)
			norm2 += (double) q[a] * (double) q[a];
		w[j] = sign * q[3];
		if (!(fabs(norm2 - 1.0) <= UNIT_SLACK))
			unit = false, w[j] = NAN;	/* marks the joint */
	}
	return unit;
}

void
modb_term_encode(const Terminator *snippets, int n, uint8 *bounds, uint8 *codes)
{
	double	   *values = palloc(sizeof(double) * n * TERM_COMPONENTS);
	double		w[N_JOINTS];
	bool		unit[N_JOINTS];
	uint16		lo[TERM_COMPONENTS],
				hi[TERM_COMPONENTS];

	for (int j = 0; j < N_JOINTS; j++)
		unit[j] = true;
	for (int i = 0; i < n; i++)
	{
		modb_term_components(&snippets[i], values + i * TERM_COMPONENTS, w);
		for (int j = 0; j < N_JOINTS; j++)
			unit[j] &= !isnan(w[j]);
	}
	memset(codes, 0, (size_t) n * TERM_CODE_BYTES);
	for (int c = 0; c < TERM_COMPONENTS; c++)
	{
		int			kind = kind_of_component(c);
		double		min = values[c],
					max = values[c],
					a,
					b;
		double		low,
					step;

		for (int i = 1; i < n; i++)
		{
			min = Min(min, values[i * TERM_COMPONENTS + c]);
			max = Max(max, values[i * TERM_COMPONENTS + c]);
		}
		a = floor((min - kind_scale[kind][0]) / scale_step(kind)) - 1;
		b = ceil((max - kind_scale[kind][0]) / scale_step(kind)) + 1;
		lo[c] = a >= 1 && a <= CODE_STEPS - 1 ? (uint16) a : 0;
		hi[c] = b >= 1 && b <= CODE_STEPS - 1 ? (uint16) b : CODE_STEPS;
		if (kind == 1 && !unit[c / TERM_JOINT_COMPONENTS])
			lo[c] = 0, hi[c] = CODE_STEPS;
		if (lo[c] == 0 || hi[c] == CODE_STEPS)
			continue;			/* unbounded: its codes say nothing */
		low = kind_scale[kind][0] + lo[c] * scale_step(kind);
		step = (kind_scale[kind][0] + hi[c] * scale_step(kind) - low) / NIBBLE_STEPS;
		for (int i = 0; i < n; i++)
		{
			double		code = floor((values[i * TERM_COMPONENTS + c] - low) / step);
			int			k = code < 0 ? 0 : (code > NIBBLE_STEPS - 1 ? NIBBLE_STEPS - 1 : (int) code);

			codes[i * TERM_CODE_BYTES + c / 2] |= (uint8) (k << (4 * (c % 2)));
		}
	}
	memcpy(bounds, lo, sizeof(lo));
	memcpy(bounds + sizeof(lo), hi, sizeof(hi));
	pfree(values);
}

/* The squared distance from x to [low, high]. */
static inline double
gap_sq(double x, double low, double high)
{
	double		d = x < low ? low - x : (x > high ? x - high : 0);

	return d * d;
}

#define WHOLE_BLOCK (-1)


/* A term's interval per component: the block's bounds (i = WHOLE_BLOCK), or snippet i's code within them. */
static inline void
interval(const TermBlock *block, int c, int i, double *low, double *high)
{
	double		step = block->step[c];
	int			k;

	if (i == WHOLE_BLOCK || step == 0)
	{
		*low = block->low[c];
		*high = block->high[c];
		return;
	}
	k = (block->codes[i * TERM_CODE_BYTES + c / 2] >> (4 * (c % 2))) & 0x0F;
	/* 1/64 of a code of margin: the encoder's own rounding */
	*low = block->low[c] + k * step - step / 64;
	*high = block->low[c] + (k + 1) * step + step / 64;
}


/* The squared distance from x to the farthest point of [low, high]. */
static inline double
reach_sq(double x, double low, double high)
{
	return Max((x - low) * (x - low), (high - x) * (high - x));
}

/*
 * Term t's squared distance (the smaller chord to +-q for a rotation) over the intervals [low, high] of its
 * components, as `distance` measures it from a point to an interval: gap_sq for the least, reach_sq for
 * the greatest.
 */
static inline double
term_sq(const TermTest *test, int t, const TermBlock *block, const double *low, const double *high,
		double (*distance) (double, double, double))
{
	int			first = test->joint[t] * TERM_JOINT_COMPONENTS + test->kind[t] * TERM_KIND_COMPONENTS;
	const double *q = test->query + first;

	if (test->kind[t] != 1)
		return distance(q[0], low[0], high[0]) + distance(q[1], low[1], high[1]) + distance(q[2], low[2], high[2]);
	if (block->step[first] == 0 || block->step[first + 1] == 0 || block->step[first + 2] == 0)
		return 0;				/* not a unit quaternion somewhere in the block: w is not known */
	{
		/* w >= 0 of a unit quaternion whose x, y, z lie in the intervals */
		double		min_sq = 0,
					max_sq = 0,
					minus = 0,
					plus = 0,
					qw = test->query[TERM_COMPONENTS + test->joint[t]];
		double		w_low,
					w_high;

		for (int a = 0; a < 3; a++)
		{
			double		l2 = low[a] * low[a],
						h2 = high[a] * high[a];

			min_sq += low[a] <= 0 && high[a] >= 0 ? 0 : Min(l2, h2);
			max_sq += Max(l2, h2);
			minus += distance(q[a], low[a], high[a]);
			plus += distance(-q[a], low[a], high[a]);
		}
		w_low = sqrt(Max(0.0, 1.0 - UNIT_SLACK - max_sq));
		w_high = sqrt(Max(0.0, 1.0 + UNIT_SLACK - min_sq));
		minus += distance(qw, w_low, w_high);
		plus += distance(-qw, w_low, w_high);
		return Min(minus, plus);
	}
}

/* The least squared distance (the smaller chord to +-q for a rotation) term t of snippet i can have. */
static double
least_sq(const TermTest *test, int t, const TermBlock *block, int i)
{
	int			first = test->joint[t] * TERM_JOINT_COMPONENTS + test->kind[t] * TERM_KIND_COMPONENTS;
	double		low[3],
				high[3];

	for (int a = 0; a < 3; a++)
		interval(block, first + a, i, &low[a], &high[a]);
	return term_sq(test, t, block, low, high, gap_sq);
}

/*
 * The greatest squared distance (the smaller chord to +-q for a rotation) a value within the block's
 * bounds can have: every snippet's own least_sq is at most its value's (the value lies in its code's
 * interval), which is at most this (the value lies in the block's bounds too).
 */
static double
greatest_sq(const TermTest *test, int t, const TermBlock *block)
{
	int			first = test->joint[t] * TERM_JOINT_COMPONENTS + test->kind[t] * TERM_KIND_COMPONENTS;

	return term_sq(test, t, block, block->low + first, block->high + first, reach_sq);
}

bool
modb_term_test(TermTest *test, const Terminator *end, const Thresholds *t, double high)
{
	double		w[N_JOINTS];
	int			order[N_JOINTS * N_TERM_KINDS];
	int			n = 0;

	modb_term_components(end, test->query, w);
	for (int j = 0; j < N_JOINTS; j++)
	{
		const float *q = end->rotations + 4 * j;

		/* the query's own quaternion as it is (its sign matches the x, y, z above) */
		test->query[TERM_COMPONENTS + j] = (q[3] < 0 ? -1.0 : 1.0) * q[3];
	}
	for (int j = 0; j < N_JOINTS; j++)
	{
		const double *thresholds[N_TERM_KINDS] = {t->position, t->angle, t->velocity, t->angular_velocity};

		if (isinf(t->position[j]) && t->position[j] > 0)
			continue;			/* a joint the profile leaves out */
		for (int k = 0; k < N_TERM_KINDS; k++)
		{
			double		threshold = thresholds[k][j];

			if (k >= 2 && !t->velocity_terms)
				continue;
			if (!(threshold > 0) || isinf(threshold))
				continue;		/* a term that is 0 (or undefined) whatever the snippet: no bound */
			order[n++] = j * N_TERM_KINDS + k;
		}
	}
	/* The terms that rejected most in this session first (a stable order: the result never depends on it). */
	for (int a = 1; a < n; a++)
		for (int b = a; b > 0 && rejections[order[b]] > rejections[order[b - 1]]; b--)
		{
			int			x = order[b];

			order[b] = order[b - 1];
			order[b - 1] = x;
		}
	test->n_terms = n;
	for (int s = 0; s < n; s++)
	{
		int			j = order[s] / N_TERM_KINDS,
					k = order[s] % N_TERM_KINDS;
		double		threshold = (k == 0 ? t->position : k == 1 ? t->angle : k == 2 ? t->velocity
								 : t->angular_velocity)[j];
		double		limit = threshold * high;
		const float *q = end->rotations + 4 * j;
		/* S = 2|a|^2 + 2|b|^2 at most, for a rotation: min chord^2 + max chord^2 = S */
		double		s_max = 2 * ((double) q[0] * q[0] + (double) q[1] * q[1] + (double) q[2] * q[2]
								 + (double) q[3] * q[3]) + 2 * (1 + UNIT_SLACK);

		test->joint[s] = j;
		test->kind[s] = k;
		/* a rotation's angle = 4 asin(chord / sqrt(S)) >= 4 chord / sqrt(S) */
		test->ratio_factor[s] = (k == 1 ? 16 / s_max : 1.0) / (threshold * threshold);
		if (k != 1)
			test->limit_sq[s] = limit * limit * (1 + LIMIT_SLACK);
		else if (limit / 4 < M_PI / 2)
		{
			/* angle > limit  <=  chord / sqrt(S) > sin(limit / 4) */
			double		sine = sin(limit / 4);

			test->limit_sq[s] = s_max * sine * sine * (1 + LIMIT_SLACK);
		}
		else
			test->limit_sq[s] = INFINITY;
	}
	return n > 0;
}

int
modb_term_block(const TermTest *test, const uint8 *bytes, const uint8 *codes, TermBlock *block)
{
	uint16		lo[TERM_COMPONENTS],
				hi[TERM_COMPONENTS];

	memcpy(lo, bytes, sizeof(lo));
	memcpy(hi, bytes + sizeof(lo), sizeof(hi));
	block->codes = codes;
	block->split = false;
	for (int t = 0; t < test->n_terms; t++)
	{
		int			first = test->joint[t] * TERM_JOINT_COMPONENTS + test->kind[t] * TERM_KIND_COMPONENTS;

		for (int c = first; c < first + TERM_KIND_COMPONENTS; c++)
		{
			int			kind = test->kind[t];
			double		low = kind_scale[kind][0] + lo[c] * scale_step(kind),
						high = kind_scale[kind][0] + hi[c] * scale_step(kind);

			if (lo[c] == 0 || hi[c] == CODE_STEPS)
			{
				block->low[c] = lo[c] == 0 ? -INFINITY : low;
				block->high[c] = hi[c] == CODE_STEPS ? INFINITY : high;
				block->step[c] = 0;
			}
			else
			{
				block->low[c] = low;
				block->high[c] = high;
				block->step[c] = (high - low) / NIBBLE_STEPS;
			}
		}
	}
	for (int t = 0; t < Min(test->n_terms, BLOCK_TERMS); t++)
		if (least_sq(test, t, block, WHOLE_BLOCK) > test->limit_sq[t])
		{
			rejections[test->joint[t] * N_TERM_KINDS + test->kind[t]]++;
			return test->kind[t];
		}
	return -1;
}

/* Which terms the block's snippets are tested on (TermBlock.split). */
static void
split_terms(const TermTest *test, TermBlock *block)
{
	block->n_tested = 0;
	block->untested_sq = 0;
	for (int t = 0; t < test->n_terms; t++)
	{
		/* with room for the rounding of either side's arithmetic */
		if (greatest_sq(test, t, block) * (1 + 1e-9) + 1e-12 <= test->limit_sq[t])
			block->untested_sq = Max(block->untested_sq,
									 least_sq(test, t, block, WHOLE_BLOCK) * test->ratio_factor[t]);
		else
			block->tested[block->n_tested++] = t;
	}
	block->split = true;
}

int
modb_term_snippet(const TermTest *test, TermBlock *block, int i, double *least_ratio)
{
	double		largest = block->split ? block->untested_sq : 0;
	int			n = block->split ? block->n_tested : test->n_terms;

	/* one square root: each term's ratio squared is at least its least square times its factor */
	for (int j = 0; j < n; j++)
	{
		int			t = block->split ? block->tested[j] : j;
		double		sq = least_sq(test, t, block, i);

		if (sq > test->limit_sq[t])
		{
			rejections[test->joint[t] * N_TERM_KINDS + test->kind[t]]++;
			return test->kind[t];
		}
		largest = Max(largest, sq * test->ratio_factor[t]);
	}
	*least_ratio = sqrt(largest) * (1 - LIMIT_SLACK);
	/* A block whose snippets are rejected early never pays for this; one with a snippet within every
	 * term likely has more */
	if (!block->split)
		split_terms(test, block);
	return -1;
}
