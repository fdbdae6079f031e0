"""Standard joint names: what a skeleton's joint map maps onto its own joints (DESIGN.md, "Joint map")."""

STANDARD_JOINTS = (
    "pelvis", "spine", "chest", "neck", "head",
    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",
    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",
)

# The indexed feature vector (terminators.py): pelvis height, these joints' positions, these joints'
# velocities, all in the local heading frame, physical units.
FEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")
FEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")
FEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]
            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])
