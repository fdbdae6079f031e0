/*
 * The objective of select_next_snippet in C: modb.aim_point, modb.target_cost, modb.approach_cost,
 * modb.world_to_local and modb.cost_to_go (82_objective.sql, 85_graph_cost_to_go.sql), operation for
 * operation as PostgreSQL evaluates the SQL (x ^ 2 is libm's pow, float4 array elements widened to float8,
 * left to right), so the fast path ranks candidates exactly as the reference query does, ties included.
 */
#include "postgres.h"

#include <math.h>

#include "modb.h"

/* SQL's x ^ 2 calls pow(); a constant exponent would let the compiler use x * x, which may round differently. */
static volatile double two = 2.0;

static double
sq(double x)
{
	return pow(x, two);
}

void
modb_aim_point(const double *target, int n, bool has_lookahead, double lookahead, double *aim)
{
	double		ground = sqrt(sq(target[0]) + sq(target[n - 1]));

	for (int i = 0; i < n; i++)
		aim[i] = target[i];
	if (!has_lookahead || lookahead >= ground)
		return;
	aim[0] = target[0] * lookahead / ground;
	aim[n - 1] = target[n - 1] * lookahead / ground;
}

double
modb_aim_direction(const double *aim, int n)
{
	return atan2(aim[0], aim[n - 1]);
}

/* The distance part of modb.target_cost: translation (3 values) to the aim ({x, z} or {x, y, z}). */
static double
distance_to(const double *translation, const double *aim, int n)
{
	return n == 3
		? sqrt(sq(translation[0] - aim[0]) + sq(translation[1] - aim[1]) + sq(translation[2] - aim[2]))
		: sqrt(sq(translation[0] - aim[0]) + sq(translation[2] - aim[1]));
}

/*
 * modb.approach_cost: least(target_cost(net), target_cost(future)), both with the future heading, so their
 * heading terms are one value (computed once; direction is modb_aim_direction's).
 */
bool
modb_approach_cost(const double *net_translation, const double *future_translation, bool has_future_heading,
				   double future_heading, const double *aim, int n, double direction, double heading_weight,
				   double *cost)
{
	double		turn;
	double		end;

	if (!has_future_heading)
		return false;			/* NULL, as in SQL: both terms use the future heading */
	turn = heading_weight * fabs(atan2(sin(future_heading - direction), cos(future_heading - direction)));
	end = distance_to(net_translation, aim, n) + turn;
	if (future_translation != NULL)
	{
		double		future = distance_to(future_translation, aim, n) + turn;

		end = future < end ? future : end;	/* least() */
	}
	*cost = end;
	return true;
}

void
modb_world_to_local(const double *origin, double heading, const double *target, int n, double *local)
{
	double		dx = target[0] - origin[0];
	double		dz = target[n - 1] - origin[2];

	local[0] = dx * cos(heading) - dz * sin(heading);
	if (n == 3)
		local[1] = target[1] - origin[1];
	local[n - 1] = dx * sin(heading) + dz * cos(heading);
}

bool
modb_cost_to_go(const float *costs, int n_costs, const double *goal, int n, const CostGrid *grid, double *seconds)
{
	double		r = sqrt(sq(goal[0]) + sq(goal[n - 1]));
	double		theta = atan2(goal[0], goal[n - 1]);
	double		ring;
	double		angle;
	double		wa,
				wj;
	int			a0,
				a1,
				j0;
	int			i00,
				i01,
				i10,
				i11;

	if (r <= grid->inner_radius)
	{
		*seconds = 0;
		return true;
	}
	ring = log((r > 1e-9 ? r : 1e-9) / grid->inner_radius) / grid->log_radius_ratio * (double) (grid->rings - 1);
	ring = ring > 0 ? ring : 0;
	ring = ring < grid->last_ring ? ring : grid->last_ring;
	angle = (theta - 2 * M_PI * floor(theta / (2 * M_PI))) / (2 * M_PI / (double) grid->angles);
	wa = angle - floor(angle);
	a0 = (int) rint(floor(angle)) % grid->angles;
	a1 = ((int) rint(floor(angle)) + 1) % grid->angles;
	wj = ring - floor(ring);
	j0 = (int) rint(floor(ring));
	i00 = a0 * grid->rings + j0;
	i01 = i00 + 1;
	i10 = a1 * grid->rings + j0;
	i11 = i10 + 1;
	if (costs == NULL || Min(Min(i00, i10), 0) < 0 || Max(i01, i11) >= n_costs)
		return false;			/* a subscript outside the array: NULL in SQL */
	*seconds = (1 - wa) * ((1 - wj) * (double) costs[i00] + wj * (double) costs[i01])
		+ wa * ((1 - wj) * (double) costs[i10] + wj * (double) costs[i11])
		+ (r - grid->outer_radius > 0 ? r - grid->outer_radius : 0) / grid->speed;
	return true;
}
