"""An authored library of canonical hand postures: grasp taxonomy types and common gestures.

Each posture is the 20-D finger part of ``theta`` (``theta[6:26]``): per digit, in the order thumb,
index, middle, ring, little, the four angles (base abduction, base flexion, middle flexion, distal
flexion). The table below is written in DEGREES; :func:`canonical_postures` returns radians.

Provenance, honestly: every angle was authored by the team. The grasp shapes follow the photographs
and descriptions of the GRASP taxonomy (Feix et al. 2016, "The GRASP Taxonomy of Human Grasp Types",
IEEE THMS 46(1); type numbers below are theirs) and of Cutkosky (1989) "On grasp choice, grasp models,
and the design of hands for manufacturing tasks"; joint magnitudes stay inside the functional ranges
of Hume et al. (1990) "Functional range of motion of the joints of the hand" (J Hand Surg 15A). The
thumb angles of contact postures (pinches, tripods, OK sign) were chosen so that the thumb pad meets
the opposing finger pad on the default skeleton of :mod:`core.model.skeleton` (checked with forward
kinematics). None of it is measured data.

Sign conventions (:mod:`core.model.skeleton`): positive flexion curls towards the palm; positive
finger abduction is ulnar (towards the little finger), so a spread hand has index < 0 and
ring, little > 0. For the thumb, positive CMC abduction swings the thumb towards the index finger in
the plane of the palm, negative CMC abduction lifts it away on the palmar side; positive CMC flexion
brings it across the palm (opposition), negative CMC flexion extends it radially.

Split (used by ``evaluate ik``): the default prior is built from every posture EXCEPT the
:data:`HELDOUT_GRASPS`, seven taxonomy types that are kept out of the prior entirely, including the
object-size variant "medium wrap" (its neighbours "large wrap" and "small wrap" are in the prior) and
the three-finger variants of the sphere and prismatic grasps (their four-finger and two-finger
neighbours are in the prior). Simulated motions through these postures test the IK on grasps the
prior has never seen.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.model.skeleton import N_POSTURE

Digit = tuple[float, float, float, float]
#: (thumb, index, middle, ring, little), each (abduction, base flexion, middle flexion, distal flexion)
PostureDeg = tuple[Digit, Digit, Digit, Digit, Digit]

# Shared finger shapes (degrees), reused by several postures below.
_FIST_FINGERS: tuple[Digit, Digit, Digit, Digit] = (
    (3, 85, 100, 60), (0, 88, 100, 60), (-3, 90, 100, 55), (-6, 90, 95, 50))
_RELAXED_FINGERS: tuple[Digit, Digit, Digit, Digit] = (
    (-2, 20, 30, 15), (0, 25, 35, 18), (2, 28, 38, 20), (5, 32, 40, 20))
_THUMB_OVER_FIST: Digit = (15, 15, 40, 55)
_THUMB_EXTENDED: Digit = (0, -20, -5, -10)
_EXTENDED: Digit = (0, 0, 5, 5)

#: Grasp taxonomy postures. Comments: taxonomy type, object, what the angles express.
GRASPS_DEG: dict[str, PostureDeg] = {
    # Feix 1 "large diameter" / Cutkosky heavy wrap, cylinder Ø ≈ 70 mm: moderate flexion at all
    # finger joints, more towards the little finger; thumb opposed around the cylinder.
    "large_wrap": ((25, 35, 20, 15), (2, 35, 45, 25), (0, 38, 48, 28), (-2, 42, 50, 28), (-4, 48, 52, 28)),
    # Feix 3 "medium wrap", cylinder Ø ≈ 45 mm: between the large and small wraps (HELD OUT).
    "medium_wrap": ((25, 20, 25, 30), (2, 50, 62, 38), (0, 52, 65, 40), (-2, 56, 66, 40), (-4, 60, 66, 38)),
    # Feix 2 "small diameter", handle Ø ≈ 25 mm: near-fist finger flexion, thumb wrapped over the
    # index and middle middle phalanges.
    "small_wrap": ((15, 20, 35, 45), (2, 65, 85, 50), (0, 68, 88, 52), (-3, 72, 88, 50), (-5, 75, 85, 45)),
    # Feix 4 "adducted thumb": medium-wrap fingers, thumb adducted along the side of the index.
    "adducted_thumb": ((35, 0, 10, 5), (2, 50, 60, 35), (0, 52, 64, 38), (-2, 55, 65, 38), (-4, 58, 65, 36)),
    # Feix 5 "light tool" (hammer, pan): small-wrap fingers, thumb lying along the handle.
    "light_tool": ((30, 5, 15, 10), (2, 60, 78, 45), (0, 65, 82, 48), (-3, 70, 84, 46), (-5, 74, 82, 42)),
    # Feix 6 "prismatic 4 finger": fingers flexed mostly at the MCP, fairly straight, pads against
    # a flat object held by the opposed thumb.
    "prismatic_4_finger": ((10, 30, 10, 10), (-2, 45, 20, 10), (0, 48, 22, 10),
                           (2, 50, 24, 12), (4, 52, 26, 12)),
    # Feix 7 "prismatic 3 finger": index, middle, ring on the object, little curled (HELD OUT).
    "prismatic_3_finger": ((10, 30, 10, 10), (-2, 45, 20, 10), (0, 48, 22, 10), (2, 52, 26, 12),
                           (5, 70, 75, 40)),
    # Feix 8 "prismatic 2 finger": index and middle on the object, ring and little curled.
    "prismatic_2_finger": ((10, 30, 10, 10), (-2, 45, 20, 10), (0, 48, 22, 10), (3, 70, 80, 45),
                           (5, 75, 80, 40)),
    # Feix 9 "palmar pinch": thumb pad against the index pad with a flat index, others relaxed.
    "palmar_pinch": ((15, 30, 0, -5), (0, 40, 30, 10), (2, 40, 40, 20), (4, 45, 45, 22), (6, 50, 48, 22)),
    # Feix 10 "power disk", lid Ø ≈ 90 mm: fingers spread around the rim, slight flexion, thumb
    # abducted across.
    "power_disk": ((10, 30, 10, 5), (-12, 40, 30, 20), (-2, 38, 32, 20), (6, 40, 32, 20), (15, 42, 30, 18)),
    # Feix 11 "power sphere", ball Ø ≈ 80 mm: spread fingers curved around the ball, palm contact.
    "power_sphere": ((15, 30, 15, 15), (-10, 35, 40, 30), (-2, 35, 42, 30),
                     (6, 38, 42, 30), (14, 42, 40, 28)),
    # Feix 12 "precision disk", jar lid Ø ≈ 70 mm: fingertips on the rim, fingers spread.
    "precision_disk": ((5, 25, 10, 5), (-14, 30, 30, 15), (-3, 30, 32, 15),
                       (7, 32, 32, 15), (18, 35, 30, 15)),
    # Feix 13 "precision sphere", ball Ø ≈ 50 mm held at the fingertips.
    "precision_sphere": ((10, 30, 10, 10), (-8, 35, 40, 25), (-1, 35, 42, 25),
                         (5, 38, 42, 25), (12, 40, 40, 22)),
    # Feix 14 "tripod": thumb, index and middle pads meet on a small object.
    "tripod": ((10, 35, 10, 10), (-2, 45, 55, 30), (2, 45, 55, 30), (4, 55, 70, 40), (6, 60, 75, 40)),
    # Feix 15 "fixed hook" / Cutkosky hook (bag handle): flexed PIP and DIP, straight MCP, thumb idle.
    "fixed_hook": ((0, -10, 0, 0), (0, 10, 85, 60), (0, 10, 88, 60), (0, 12, 88, 58), (2, 15, 85, 55)),
    # Feix 16 "lateral" (key pinch): thumb pad presses the radial side of the index middle phalanx.
    "lateral_pinch": ((20, 5, 25, 25), (2, 55, 70, 45), (4, 65, 80, 50), (6, 70, 85, 50), (8, 75, 85, 45)),
    # Feix 17 "index finger extension" (knife): small-wrap fingers, index extended along the handle.
    "index_finger_extension": ((25, 5, 15, 15), (0, 25, 10, 5), (0, 65, 85, 50), (-3, 70, 86, 48),
                               (-5, 74, 84, 44)),
    # Feix 18 "extension type" (holding a plate edge): straight fingers flexed at the MCP, thumb below.
    "extension_type": ((5, 25, 5, 0), (-3, 35, 5, 5), (0, 35, 5, 5), (2, 35, 5, 5), (4, 35, 5, 5)),
    # Feix 20 "writing tripod": pen on the radial side of the middle distal phalanx, index and thumb
    # pads on top, ring and little curled.
    "writing_tripod": ((15, 30, 10, 20), (0, 40, 40, 10), (3, 45, 60, 30), (4, 60, 80, 45), (6, 65, 85, 45)),
    # Feix 22 "parallel extension" (book): straight fingers at moderate MCP flexion, thumb pad
    # opposite (HELD OUT).
    "parallel_extension": ((0, 40, 0, -5), (-2, 55, 5, 0), (0, 55, 5, 0), (2, 55, 5, 0), (4, 55, 5, 0)),
    # Feix 23 "adduction grip" (cigarette between index and middle): index abducted towards the
    # middle finger, both extended, others relaxed (HELD OUT).
    "adduction_grip": ((5, 10, 10, 10), (8, 20, 15, 10), (-6, 20, 15, 10), (2, 45, 55, 30), (5, 50, 55, 28)),
    # Feix 24 "tip pinch" (needle): index tip on the thumb tip, index strongly curled.
    "tip_pinch": ((10, 25, 15, 5), (0, 45, 60, 45), (2, 50, 65, 40), (4, 55, 70, 40), (6, 60, 70, 40)),
    # Feix 25 "lateral tripod": lateral pinch with the middle finger supporting from below (HELD OUT).
    "lateral_tripod": ((20, 5, 20, 20), (2, 50, 65, 40), (2, 55, 60, 30), (6, 70, 85, 50), (8, 75, 85, 45)),
    # Feix 26 "sphere 4 finger", ball Ø ≈ 60 mm: like power sphere, little finger tucked.
    "sphere_4_finger": ((15, 30, 15, 15), (-8, 40, 45, 30), (-1, 40, 48, 30),
                        (6, 42, 48, 30), (8, 70, 75, 40)),
    # Feix 27 "quadpod": thumb, index, middle and ring tips around a small object (HELD OUT).
    "quadpod": ((10, 35, 10, 10), (-4, 45, 50, 30), (0, 45, 52, 30), (3, 48, 55, 32), (6, 60, 72, 40)),
    # Feix 28 "sphere 3 finger", ball Ø ≈ 50 mm: ring and little tucked (HELD OUT).
    "sphere_3_finger": ((15, 30, 15, 15), (-8, 40, 45, 30), (-1, 42, 48, 30),
                        (6, 70, 78, 42), (8, 72, 75, 40)),
    # Feix 29 "stick" (holding a pole across the palm): fingers wrapped, thumb adducted.
    "stick": ((30, 0, 10, 10), (0, 70, 80, 40), (0, 72, 82, 42), (-2, 74, 82, 40), (-4, 76, 80, 38)),
    # Feix 31 "ring" (around a bottle neck): thumb and index form a ring, others follow loosely.
    "ring": ((5, 20, 10, 5), (0, 40, 50, 30), (0, 45, 50, 28), (2, 50, 52, 26), (4, 55, 52, 24)),
    # Feix 33 "inferior pincer": thumb pad meets a nearly straight index pad.
    "inferior_pincer": ((15, 30, 5, 0), (0, 40, 20, 5), (2, 40, 40, 20), (4, 45, 45, 22), (6, 50, 48, 22)),
    # Cutkosky "platform": flat hand supporting an object from below, fingers together.
    "platform": ((5, -10, 0, 0), (3, 0, 0, 0), (0, 0, 0, 0), (-2, 0, 0, 0), (-5, 0, 0, 0)),
}

#: Common gestures. Angles authored from the usual appearance of each gesture.
GESTURES_DEG: dict[str, PostureDeg] = {
    # Flat hand, fingers together and straight, thumb in the plane of the palm.
    "flat": ((0, -15, 0, 0), (2, 0, 0, 0), (0, 0, 0, 0), (-1, 0, 0, 0), (-3, 0, 0, 0)),
    # Relaxed hand at rest: the natural light curl, increasing towards the little finger.
    "relaxed": ((10, 10, 10, 10), *_RELAXED_FINGERS),
    # Closed fist, thumb across the index and middle middle phalanges.
    "fist": (_THUMB_OVER_FIST, *_FIST_FINGERS),
    # Pointing with the index finger.
    "point": (_THUMB_OVER_FIST, _EXTENDED, *_FIST_FINGERS[1:]),
    # Peace / V sign: index and middle extended and spread, thumb holding the ring finger.
    "peace": ((20, 20, 40, 45), (-12, 0, 5, 5), (10, 0, 5, 5), *_FIST_FINGERS[2:]),
    # Thumbs up: fist with the thumb extended.
    "thumbs_up": (_THUMB_EXTENDED, *_FIST_FINGERS),
    # OK sign: thumb and index pads touch in a ring, other fingers extended and slightly spread.
    "ok_sign": ((10, 25, 15, 15), (-2, 45, 60, 35), (4, 10, 10, 5), (6, 12, 12, 6), (12, 15, 15, 8)),
    # Counting (one = index, ..., four = four fingers with the thumb folded across the palm).
    "count_1": ((25, 10, 30, 30), (-2, 0, 5, 5), *_FIST_FINGERS[1:]),
    "count_2": ((20, 20, 40, 45), (-6, 0, 5, 5), (4, 0, 5, 5), *_FIST_FINGERS[2:]),
    "count_3": ((25, 30, 40, 40), (-8, 0, 5, 5), (0, 0, 5, 5), (6, 0, 5, 5), _FIST_FINGERS[3]),
    "count_4": ((40, 45, 30, 20), (-8, 0, 5, 5), (-1, 0, 5, 5), (5, 0, 5, 5), (14, 0, 5, 5)),
    "count_5": ((-5, -20, -5, -5), (-12, 0, 0, 0), (-2, 0, 0, 0), (7, 0, 0, 0), (18, 0, 0, 0)),
    # Fingers spread as far as comfortable, thumb abducted radially.
    "spread": ((-10, -25, -5, -5), (-18, -5, 0, 0), (-3, -5, 0, 0), (10, -5, 0, 0), (25, -5, 0, 0)),
    # Claw: MCP straight or hyperextended, PIP and DIP flexed.
    "claw": ((5, 20, 30, 40), (-8, -10, 80, 60), (-2, -10, 80, 60), (5, -10, 80, 60), (12, -10, 78, 55)),
    # Pinch open: thumb and index pads about 5 cm apart, others relaxed.
    "pinch_open": ((0, 10, 5, 5), (-2, 25, 25, 10), *_RELAXED_FINGERS[1:]),
    # Pinch closed: thumb and index pads touching, others relaxed.
    "pinch_closed": ((10, 30, 10, 10), (0, 40, 45, 20), (2, 45, 50, 25), (4, 45, 55, 25), (6, 50, 55, 25)),
}

#: Grasp types kept OUT of the default prior (see the module docstring).
HELDOUT_GRASPS: tuple[str, ...] = (
    "medium_wrap", "prismatic_3_finger", "parallel_extension", "adduction_grip",
    "lateral_tripod", "quadpod", "sphere_3_finger",
)


def _to_radians(table: dict[str, PostureDeg]) -> dict[str, np.ndarray]:
    return {name: np.radians(np.asarray(digits, dtype=float).reshape(N_POSTURE))
            for name, digits in table.items()}


def canonical_postures() -> dict[str, np.ndarray]:
    """Every authored posture (grasps and gestures): name -> ``(20,)`` finger angles in radians."""
    return _to_radians(GRASPS_DEG) | _to_radians(GESTURES_DEG)


def prior_postures() -> dict[str, np.ndarray]:
    """The postures the default prior is built from: all canonical ones but the held-out grasps."""
    return {name: vector for name, vector in canonical_postures().items() if name not in HELDOUT_GRASPS}


def prior_grasp_postures() -> dict[str, np.ndarray]:
    """Grasp taxonomy postures that are in the prior set (for scripted grasp motions), radians ``(20,)``."""
    return {name: vector for name, vector in _to_radians(GRASPS_DEG).items() if name not in HELDOUT_GRASPS}


def heldout_grasp_postures() -> dict[str, np.ndarray]:
    """The grasp postures that are NOT in the prior set, radians ``(20,)``."""
    grasps = _to_radians(GRASPS_DEG)
    return {name: grasps[name] for name in HELDOUT_GRASPS}
