"""Standard joint names: what a skeleton's joint map maps onto its own joints.

DESIGN.md, "Joint map".
"""

STANDARD_JOINTS = (
    "pelvis",
    "spine",
    "chest",
    "neck",
    "head",
    "left_hip",
    "left_knee",
    "left_ankle",
    "left_toe",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_hip",
    "right_knee",
    "right_ankle",
    "right_toe",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
)

# The indexed feature vector (terminators.py): pelvis height, these joints' positions, these joints'
# velocities, all in the local heading frame, physical units; then, for the joints whose angle
# thresholds reject most candidates (neck and head, then the wrists, on real data: BENCHMARKS
# "Selection at scale"), the first two columns of their rotation matrix (entries R_xx, R_yx, R_zx,
# R_xy, R_yy, R_zy): the same for q and -q, and within 2 sin(angle / 2) of another rotation's, so
# the box can bound the angle too.
FEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")
FEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")
FEATURE_ROTATIONS = ("neck", "head", "left_wrist", "right_wrist")
FEATURES = (
    ["pelvis.y"]
    + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]
    + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"]
    + [f"{j}.R{row}{column}" for j in FEATURE_ROTATIONS for column in "xy" for row in "xyz"]
)
