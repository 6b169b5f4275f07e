"""The 16-joint, 26-parameter hand skeleton: joint names, parameter layout, rest geometry, limits.

Conventions (DESIGN.md "The hand model"):

* World frame of the rest pose (right hand): wrist joint at the origin, fingers along +Y, back of the
  hand (dorsal side) towards +Z, thumb on the -X (radial) side. Millimetres.
* Joints: 0 = wrist, then per digit (thumb, index, middle, ring, little) base, middle, distal joint;
  for the thumb base = CMC, middle = MCP, distal = IP.
* Parameters ``theta (26,)``: ``[0:3]`` wrist translation (mm), ``[3:6]`` wrist rotation vector (rad),
  ``[6:26]`` four per digit: base abduction, base flexion, middle flexion, distal flexion (rad).
* Every finger joint has a rest frame whose columns are: x = flexion axis, y = bone direction
  (towards the child joint), z = x × y = palmar direction. Positive flexion curls the digit towards
  the palm; positive abduction rotates the bone about the palmar axis z, i.e. towards the ulnar
  (little-finger) side for the fingers and across the palm for the thumb.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DIGITS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "little")
THUMB_JOINTS = ("cmc", "mcp", "ip")
FINGER_JOINTS = ("mcp", "pip", "dip")

JOINT_NAMES: tuple[str, ...] = ("wrist",) + tuple(
    f"{digit}_{joint}"
    for digit in DIGITS
    for joint in (THUMB_JOINTS if digit == "thumb" else FINGER_JOINTS)
)
N_JOINTS = 16
N_PARAMS = 26
N_GLOBAL = 6
N_POSTURE = 20

#: parent joint index per joint (-1 for the wrist)
JOINT_PARENTS = np.array([-1] + [p for d in range(5) for p in (0, 1 + 3 * d, 2 + 3 * d)], dtype=np.int64)

PARAM_NAMES: tuple[str, ...] = (
    "wrist_tx", "wrist_ty", "wrist_tz", "wrist_rx", "wrist_ry", "wrist_rz",
) + tuple(
    f"{digit}_{name}"
    for digit in DIGITS
    for name in (
        ("cmc_abduction", "cmc_flexion", "mcp_flexion", "ip_flexion")
        if digit == "thumb"
        else ("mcp_abduction", "mcp_flexion", "pip_flexion", "dip_flexion")
    )
)

#: joint moved by each parameter (-1 for the six global parameters)
PARAM_JOINT = np.array([-1] * 6 + [j for d in range(5) for j in (1 + 3 * d, 1 + 3 * d, 2 + 3 * d, 3 + 3 * d)],
                       dtype=np.int64)
#: 0 = rotation about the joint's local z (abduction), 1 = about local x (flexion); -1 global
PARAM_AXIS = np.array([-1] * 6 + [0, 1, 1, 1] * 5, dtype=np.int64)


# Default joint limits in degrees, active range of motion of adult hands. Sources: finger MCP/PIP/DIP
# and thumb ranges from Hume et al. (1990) "Functional range of motion of the joints of the hand",
# J Hand Surg 15A:240-243, and the 26-DoF model limits of Cobos et al. (2008) "Efficient human hand
# kinematics for manipulation tasks", IROS; abduction ranges from Lee & Kunii (1995). A posture
# prior may narrow them. Wrist translation and rotation are unlimited.
DEFAULT_LIMITS_DEG: dict[str, tuple[float, float]] = {
    "thumb_cmc_abduction": (-30.0, 45.0),
    "thumb_cmc_flexion": (-25.0, 55.0),
    "thumb_mcp_flexion": (-10.0, 60.0),
    "thumb_ip_flexion": (-15.0, 85.0),
    "index_mcp_abduction": (-20.0, 25.0),
    "middle_mcp_abduction": (-15.0, 15.0),
    "ring_mcp_abduction": (-15.0, 15.0),
    "little_mcp_abduction": (-15.0, 30.0),
    "mcp_flexion": (-25.0, 90.0),
    "pip_flexion": (-5.0, 110.0),
    "dip_flexion": (-10.0, 90.0),
}


def default_joint_limits() -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits ``(26,)`` each, radians (±inf for the global parameters)."""
    lower = np.full(N_PARAMS, -np.inf)
    upper = np.full(N_PARAMS, np.inf)
    for index, name in enumerate(PARAM_NAMES[6:], start=6):
        key = name if name in DEFAULT_LIMITS_DEG else name.split("_", 1)[1]
        low, high = DEFAULT_LIMITS_DEG[key]
        lower[index], upper[index] = np.radians(low), np.radians(high)
    return lower, upper


@dataclass(frozen=True)
class HandProportions:
    """Parametric description of a hand (mm). Scale factors re-proportion it for synthetic subjects."""

    #: knuckle (base joint) positions relative to the wrist, rest pose, per digit (5, 3)
    base_positions: np.ndarray = field(default_factory=lambda: np.array([
        [-24.0, 24.0, -10.0],   # thumb CMC
        [-26.0, 86.0, 0.0],     # index MCP
        [-7.0, 89.0, 0.0],      # middle MCP
        [11.0, 84.0, 0.0],      # ring MCP
        [27.0, 74.0, -2.0],     # little MCP
    ]))
    #: segment lengths base->middle, middle->distal, distal->tip per digit (5, 3)
    segment_lengths: np.ndarray = field(default_factory=lambda: np.array([
        [44.0, 32.0, 27.0],
        [41.0, 24.0, 20.0],
        [46.0, 28.0, 21.0],
        [43.0, 27.0, 21.0],
        [34.0, 20.0, 19.0],
    ]))
    #: bone direction of each digit at rest (5, 3), unit after normalisation
    bone_directions: np.ndarray = field(default_factory=lambda: np.array([
        [-0.62, 0.72, -0.30],
        [-0.07, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.06, 1.0, 0.0],
        [0.14, 1.0, 0.0],
    ]))
    #: palmar direction of the thumb pad at rest (it faces the fingers), orthogonalised later
    thumb_palmar: np.ndarray = field(default_factory=lambda: np.array([0.65, 0.25, -0.72]))
    #: finger radius (mm) at base, middle and distal segment per digit (5, 3)
    finger_radii: np.ndarray = field(default_factory=lambda: np.array([
        [12.0, 10.5, 9.5],
        [10.0, 8.8, 8.0],
        [10.2, 9.0, 8.2],
        [9.6, 8.5, 7.8],
        [8.6, 7.6, 7.0],
    ]))
    palm_thickness: float = 30.0
    wrist_width: float = 58.0
    wrist_thickness: float = 36.0

    def scaled(self, finger_scale: np.ndarray | float = 1.0, palm_width_scale: float = 1.0,
               palm_length_scale: float = 1.0) -> HandProportions:
        """A re-proportioned hand: ``finger_scale`` scales segment lengths (scalar or per digit (5,)),
        ``palm_width_scale`` the knuckle spread (X), ``palm_length_scale`` the knuckle distance (Y)."""
        finger_scale = np.broadcast_to(np.asarray(finger_scale, dtype=float), (5,))
        base = self.base_positions * np.array([palm_width_scale, palm_length_scale, 1.0])
        return HandProportions(
            base_positions=base,
            segment_lengths=self.segment_lengths * finger_scale[:, None],
            bone_directions=self.bone_directions.copy(),
            thumb_palmar=self.thumb_palmar.copy(),
            finger_radii=self.finger_radii * np.sqrt(palm_width_scale),
            palm_thickness=self.palm_thickness,
            wrist_width=self.wrist_width * palm_width_scale,
            wrist_thickness=self.wrist_thickness,
        )


@dataclass(frozen=True)
class Skeleton:
    """Rest geometry of the 16 joints (world frame of the rest pose, mm).

    ``rest_positions (16, 3)``: joint centres; ``rest_rotations (16, 3, 3)``: joint frames (columns
    x = flexion axis, y = bone direction, z = palmar); ``tip_positions (5, 3)``: digit tips.
    """

    rest_positions: np.ndarray
    rest_rotations: np.ndarray
    tip_positions: np.ndarray
    side: str = "right"

    @property
    def abduction_sign(self) -> float:
        """+1 for a right hand, -1 for a left one: keeps positive abduction ulnar after mirroring."""
        return 1.0 if self.side == "right" else -1.0

    def bone_lengths(self) -> np.ndarray:
        """Length (mm) of each digit segment, ``(5, 3)``: base->middle, middle->distal, distal->tip."""
        lengths = np.empty((5, 3))
        for digit in range(5):
            joints = [1 + 3 * digit + k for k in range(3)]
            points = np.vstack([self.rest_positions[joints], self.tip_positions[digit]])
            lengths[digit] = np.linalg.norm(np.diff(points, axis=0), axis=1)
        return lengths

    def local_offsets(self) -> np.ndarray:
        """Each joint's rest position in its parent's rest frame, ``(16, 3)`` (zeros for the wrist)."""
        offsets = np.zeros((N_JOINTS, 3))
        for joint in range(1, N_JOINTS):
            parent = JOINT_PARENTS[joint]
            offsets[joint] = self.rest_rotations[parent].T @ (self.rest_positions[joint]
                                                               - self.rest_positions[parent])
        return offsets

    def relative_rest_rotations(self) -> np.ndarray:
        """``R_parent_restᵀ R_joint_rest`` per joint, ``(16, 3, 3)`` (identity for the wrist)."""
        relative = np.tile(np.eye(3), (N_JOINTS, 1, 1))
        for joint in range(1, N_JOINTS):
            parent = JOINT_PARENTS[joint]
            relative[joint] = self.rest_rotations[parent].T @ self.rest_rotations[joint]
        return relative

    def mirrored(self) -> Skeleton:
        """The left-hand skeleton: X mirrored; frames keep flexion and abduction semantics."""
        mirror = np.diag([-1.0, 1.0, 1.0])
        rotations = mirror @ self.rest_rotations
        # Mirroring flips handedness; negating the x (flexion) column restores a rotation whose
        # positive flexion still curls the finger, and z = x × y stays palmar after mirroring.
        rotations[:, :, 0] *= -1.0
        rotations[:, :, 2] = np.cross(rotations[:, :, 0], rotations[:, :, 1])
        rotations[0] = np.eye(3)
        return Skeleton(
            rest_positions=self.rest_positions @ mirror,
            rest_rotations=rotations,
            tip_positions=self.tip_positions @ mirror,
            side="left" if self.side == "right" else "right",
        )


def _frame(bone_direction: np.ndarray, palmar_hint: np.ndarray) -> np.ndarray:
    """Right-handed frame (3, 3): y along the bone, z palmar (orthogonalised), x = y × z."""
    y_axis = bone_direction / np.linalg.norm(bone_direction)
    z_axis = palmar_hint - (palmar_hint @ y_axis) * y_axis
    z_axis /= np.linalg.norm(z_axis)
    x_axis = np.cross(y_axis, z_axis)
    return np.column_stack([x_axis, y_axis, z_axis])


def build_skeleton(proportions: HandProportions | None = None) -> Skeleton:
    """Rest skeleton of a right hand with the given proportions (default: an adult hand, L ≈ 190 mm)."""
    proportions = proportions or HandProportions()
    positions = np.zeros((N_JOINTS, 3))
    rotations = np.tile(np.eye(3), (N_JOINTS, 1, 1))
    tips = np.zeros((5, 3))
    for digit in range(5):
        direction = proportions.bone_directions[digit] / np.linalg.norm(proportions.bone_directions[digit])
        palmar = proportions.thumb_palmar if digit == 0 else np.array([0.0, 0.0, -1.0])
        frame = _frame(direction, palmar)
        point = proportions.base_positions[digit].astype(float)
        for segment in range(3):
            joint = 1 + 3 * digit + segment
            positions[joint] = point
            rotations[joint] = frame
            point = point + direction * proportions.segment_lengths[digit, segment]
        tips[digit] = point
    return Skeleton(rest_positions=positions, rest_rotations=rotations, tip_positions=tips)
