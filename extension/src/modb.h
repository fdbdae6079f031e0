/*
 * Constants the C files share with the rest of modb. Each has one source: standard_joints.h is generated
 * by the Makefile from plpython/modb_kernel/joints.py (build_sql.py --c-header).
 */
#ifndef MODB_H
#define MODB_H

#include "standard_joints.h"	/* N_JOINTS: how many standard joints a terminator's arrays hold */

#endif							/* MODB_H */
