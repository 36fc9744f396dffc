"""Segment lengths, masses, centres of mass and radii of gyration (de Leva 1996).

de Leva, P. (1996). Adjustments to Zatsiorsky-Seluyanov's segment inertia
parameters. J. Biomechanics 29(9), 1223-1230, Tables 4 (male) and 4 (female):
segment length (mm, for the reference subject), mass (% of body mass), centre
of mass (% of the segment length from the proximal end point), radii of
gyration (% of the segment length) about the sagittal, transverse and
longitudinal axes. The trunk uses the three-part subdivision (upper, middle,
lower trunk). Lengths are scaled by height / reference height, masses by body
mass; radii stay proportional to the scaled lengths.

Axes convention here: the "sagittal" radius is about the antero-posterior
axis (y in the body frame), the "transverse" radius about the medio-lateral
axis (x), the "longitudinal" radius about the segment's long axis (z).

Segments de Leva does not tabulate (clavicle-scapula unit, neck) are carved
out of their neighbours so the total mass stays the body mass: each shoulder
girdle takes 0.7 % of body mass from the upper trunk; the neck takes a quarter
of de Leva's head (which includes the neck), keeping the head-neck centre of
mass where de Leva puts it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

Sex = Literal["male", "female"]
SkeletonUnits = Literal["auto", "m", "cm", "mm", "in"]
"""A skeleton file's length unit as ``--skeleton-units`` takes it (``batteur render``, the physics node): ``auto``,
guessed from the performer its lengths make (:func:`services.physics.bvh_motion.read_skeleton`), or the unit the
user knows the file is in (``services.physics.bvh_motion.METRES_PER_SKELETON_UNIT``'s keys). Here, not beside the
reader: the settings and the render's parser name it without importing scipy."""
SKELETON_UNITS: tuple[str, ...] = get_args(SkeletonUnits)


@dataclass(frozen=True)
class SegmentRow:
    """One row of de Leva's table (reference subject)."""

    length_mm: float
    mass_pct: float
    com_pct: float
    r_sag_pct: float
    r_trans_pct: float
    r_long_pct: float


REFERENCE = {"male": (1741.0, 73.0), "female": (1735.0, 61.9)}
"""Reference stature (mm) and mass (kg) of de Leva's subjects."""

# Head: VERT-CERV; trunk parts: CERV-XYPH, XYPH-OMPH, OMPH-MIDH; upper arm SJC-EJC;
# forearm EJC-WJC; hand WJC-MET3; thigh HJC-KJC; shank KJC-LMAL; foot HEEL-TTIP.
DE_LEVA: dict[Sex, dict[str, SegmentRow]] = {
    "male": {
        "head": SegmentRow(242.9, 6.94, 59.76, 36.2, 37.6, 31.2),
        "upper_trunk": SegmentRow(242.1, 15.96, 29.99, 71.6, 45.4, 65.9),
        "middle_trunk": SegmentRow(215.5, 16.33, 45.02, 48.2, 38.3, 46.8),
        "lower_trunk": SegmentRow(145.7, 11.17, 61.15, 61.5, 55.1, 58.7),
        "upper_arm": SegmentRow(281.7, 2.71, 57.72, 28.5, 26.9, 15.8),
        "forearm": SegmentRow(268.9, 1.62, 45.74, 27.6, 26.5, 12.1),
        "hand": SegmentRow(86.2, 0.61, 79.00, 62.8, 51.3, 40.1),
        "thigh": SegmentRow(422.2, 14.16, 40.95, 32.9, 32.9, 14.9),
        "shank": SegmentRow(434.0, 4.33, 44.59, 25.5, 24.9, 10.3),
        "foot": SegmentRow(258.1, 1.37, 44.15, 25.7, 24.5, 12.4),
    },
    "female": {
        "head": SegmentRow(243.7, 6.68, 58.94, 33.0, 35.9, 31.8),
        "upper_trunk": SegmentRow(228.0, 15.45, 20.77, 74.6, 50.2, 71.8),
        "middle_trunk": SegmentRow(205.3, 14.65, 45.12, 43.3, 35.4, 41.5),
        "lower_trunk": SegmentRow(181.5, 12.47, 49.20, 43.3, 40.2, 44.4),
        "upper_arm": SegmentRow(275.1, 2.55, 57.54, 27.8, 26.0, 14.8),
        "forearm": SegmentRow(264.3, 1.38, 45.59, 26.1, 25.7, 9.4),
        "hand": SegmentRow(78.0, 0.56, 74.74, 53.1, 45.4, 33.5),
        "thigh": SegmentRow(368.5, 14.78, 36.12, 36.9, 36.4, 16.2),
        "shank": SegmentRow(432.3, 4.81, 44.16, 27.1, 26.7, 9.3),
        "foot": SegmentRow(228.3, 1.29, 40.14, 29.9, 27.9, 13.9),
    },
}

SHOULDER_GIRDLE_MASS_PCT = 0.7
NECK_SHARE_OF_HEAD = 0.25
NECK_LENGTH_SHARE = 0.35
"""The neck link spans this share of de Leva's VERT-CERV length, from CERV up."""

CLAVICLE_MIDLINE_OFFSET = 0.015
"""Each sternoclavicular joint's distance from the midline / de Leva's scale (metres at the reference
stature); the clavicle spans the rest of the half shoulder width."""
SEGMENT_NAMES = ("pelvis", "abdomen", "thorax", "neck", "head", "clavicle", "upper_arm", "forearm", "hand", "thigh",
                 "shank", "foot")
"""Every segment :func:`anthropometry` makes (one of each side-independent kind)."""
SHOULDER_BELOW_NECK = 0.02
"""The shoulder joint centres' height below the neck joint / de Leva's scale (metres at the reference
stature)."""
TRUNK_SEGMENTS = ("pelvis", "abdomen", "thorax")
"""The trunk from the hip joint centres up to the neck joint, bottom to top."""
WHOLE_LENGTHS: dict[str, tuple[float, float]] = {
    "trunk": (0.2, 1.2), "shoulder_height": (0.2, 1.2), "shoulder_width": (0.15, 0.8), "hip_width": (0.08, 0.5)}
"""Lengths of :func:`anthropometry`'s ``lengths_m`` that are not one segment's -> plausible range, metres.
``trunk``: the neck joint's height above the hip joint centres (the pelvis, abdomen and thorax share it in the
table's proportions); ``shoulder_height``: the shoulder joint centres' height above the hip joint centres (the
trunk follows: :data:`SHOULDER_BELOW_NECK` shorter); ``shoulder_width``: between the shoulder joint centres (the
clavicles follow); ``hip_width``: between the hip joint centres."""

SHOULDER_WIDTH_RATIO = 0.20
"""Distance between the shoulder joint centres / stature."""
HIP_WIDTH_RATIO = 0.105
"""Distance between the hip joint centres / stature."""


@dataclass(frozen=True)
class Segment:
    """A body segment scaled to a performer.

    ``length_m``: end point to end point; ``mass_kg``; ``com_from_proximal_m``
    along the segment from its proximal joint; ``radii_m``: radii of gyration
    (about x: medio-lateral, y: antero-posterior, z: long axis).
    """

    name: str
    length_m: float
    mass_kg: float
    com_from_proximal_m: float
    radii_m: tuple[float, float, float]

    def inertia(self) -> tuple[float, float, float]:
        """Principal moments (ixx, iyy, izz) about the centre of mass, kg m^2."""
        rx, ry, rz = self.radii_m
        return (self.mass_kg * rx * rx, self.mass_kg * ry * ry, self.mass_kg * rz * rz)


@dataclass(frozen=True)
class Anthropometry:
    """Segments of one performer (height m, mass kg) from de Leva's table."""

    height_m: float
    mass_kg: float
    sex: Sex
    segments: dict[str, Segment]
    shoulder_width_m: float
    """Distance between the shoulder joint centres, metres."""
    hip_width_m: float
    """Distance between the hip joint centres, metres."""

    @property
    def scale(self) -> float:
        return self.height_m * 1000.0 / REFERENCE[self.sex][0]


def _segment(name: str, row: SegmentRow, scale: float, mass_kg: float, com_from_distal: bool = False) -> Segment:
    length = row.length_mm / 1000.0 * scale
    mass = row.mass_pct / 100.0 * mass_kg
    com = row.com_pct / 100.0 * length
    if com_from_distal:
        com = length - com
    return Segment(name, length, mass, com,
                   (row.r_trans_pct / 100 * length, row.r_sag_pct / 100 * length, row.r_long_pct / 100 * length))


def anthropometry(height_m: float = 1.75, mass_kg: float = 73.0, sex: Sex = "male",
                  lengths_m: dict[str, float] | None = None) -> Anthropometry:
    """Scale de Leva's table to a performer.

    Parameters
    ----------
    height_m : float
        Stature, metres (1.2 ... 2.2).
    mass_kg : float
        Body mass, kilograms (35 ... 150).
    sex : {"male", "female"}
        Which table.
    lengths_m : dict, optional
        Lengths (metres) overriding the scaled table, e.g. measured from a
        BVH skeleton (:func:`services.physics.bvh_motion.bvh_segment_lengths`):
        segments (:data:`SEGMENT_NAMES`) and :data:`WHOLE_LENGTHS` (``trunk``
        or ``shoulder_height``, ``shoulder_width``, ``hip_width``); a segment
        named itself wins over the trunk. Masses stay from the table, centres of mass and radii follow
        the lengths.

    Returns
    -------
    Anthropometry
        Segments: pelvis, abdomen, thorax, neck, head, clavicle, upper_arm,
        forearm, hand, thigh, shank, foot (one of each side-independent kind).
    """
    if not 1.2 <= height_m <= 2.2:
        raise ValueError(f"height must be 1.2 ... 2.2 m, got {height_m}")
    if not 35.0 <= mass_kg <= 150.0:
        raise ValueError(f"mass must be 35 ... 150 kg, got {mass_kg}")
    table = DE_LEVA[sex]
    scale = height_m * 1000.0 / REFERENCE[sex][0]
    seg: dict[str, Segment] = {}
    # trunk: de Leva's proximal end is the upper point (CERV, XYPH, OMPH); our chain runs pelvis -> up,
    # so centres of mass are measured from the lower (distal) end
    seg["pelvis"] = _segment("pelvis", table["lower_trunk"], scale, mass_kg, com_from_distal=True)
    seg["abdomen"] = _segment("abdomen", table["middle_trunk"], scale, mass_kg, com_from_distal=True)
    thorax = _segment("thorax", table["upper_trunk"], scale, mass_kg, com_from_distal=True)
    girdle_mass = SHOULDER_GIRDLE_MASS_PCT / 100.0 * mass_kg
    seg["thorax"] = Segment("thorax", thorax.length_m, thorax.mass_kg - 2 * girdle_mass, thorax.com_from_proximal_m,
                            thorax.radii_m)
    head = _segment("head", table["head"], scale, mass_kg, com_from_distal=True)  # COM measured from CERV up
    neck_len = NECK_LENGTH_SHARE * head.length_m
    neck_mass = NECK_SHARE_OF_HEAD * head.mass_kg
    head_mass = head.mass_kg - neck_mass
    head_com_above_cerv = (head.mass_kg * head.com_from_proximal_m - neck_mass * neck_len / 2) / head_mass
    seg["neck"] = Segment("neck", neck_len, neck_mass, neck_len / 2, (0.3 * neck_len, 0.3 * neck_len, 0.25 * neck_len))
    seg["head"] = Segment("head", head.length_m - neck_len, head_mass, head_com_above_cerv - neck_len, head.radii_m)
    for name, key in (("upper_arm", "upper_arm"), ("forearm", "forearm"), ("hand", "hand"), ("thigh", "thigh"),
                      ("shank", "shank"), ("foot", "foot")):
        seg[name] = _segment(name, table[key], scale, mass_kg)
    given = _checked_lengths(lengths_m or {})
    widths = {"shoulder_width": SHOULDER_WIDTH_RATIO * height_m, "hip_width": HIP_WIDTH_RATIO * height_m}
    widths.update({k: v for k, v in given.items() if k in widths})
    clav_len = widths["shoulder_width"] / 2 - CLAVICLE_MIDLINE_OFFSET * scale  # as the character places it
    if clav_len < 0.01:
        raise LengthError(f"shoulder_width {_rounded(widths['shoulder_width'])} m is implausible for a performer of "
                         f"{_rounded(height_m)} m (no room for the clavicles)", "shoulder_width")
    seg["clavicle"] = Segment("clavicle", clav_len, girdle_mass, clav_len / 2,
                              (0.2 * clav_len, 0.3 * clav_len, 0.3 * clav_len))
    if "shoulder_height" in given:
        given["trunk"] = given.pop("shoulder_height") + SHOULDER_BELOW_NECK * scale
    if "trunk" in given:  # one length for three segments: each keeps its share of the table's trunk
        table_trunk = sum(seg[name].length_m for name in TRUNK_SEGMENTS)
        for name in TRUNK_SEGMENTS:
            seg[name] = _resized(seg[name], seg[name].length_m * given["trunk"] / table_trunk)
    for name, length in given.items():
        if name in seg:
            seg[name] = _resized(seg[name], length)
    seg = {name: seg[name] for name in SEGMENT_NAMES}  # in the table's order
    return Anthropometry(height_m, mass_kg, sex, seg, widths["shoulder_width"], widths["hip_width"])


class LengthError(ValueError):
    """A length given (``lengths_m``) that no body has; ``segment`` is its name (a key of ``lengths_m``), so that a
    caller can say where it was measured (a skeleton's joints)."""

    def __init__(self, message: str, segment: str) -> None:
        super().__init__(message)
        self.segment = segment


def _checked_lengths(lengths_m: dict[str, float]) -> dict[str, float]:
    """``lengths_m`` if every name is a segment or one of :data:`WHOLE_LENGTHS` and every length plausible;
    else ``ValueError`` naming the first that is not."""
    known = (*SEGMENT_NAMES, *WHOLE_LENGTHS)
    for name, length in lengths_m.items():
        if name not in known:
            raise ValueError(f"unknown segment {name!r} (known: {', '.join(known)})")
        low, high = WHOLE_LENGTHS.get(name, (0.01, 1.5))
        if not low <= length <= high:
            raise LengthError(f"segment {name} length {_rounded(length)} m is implausible (expected {low:g} ... "
                              f"{high:g} m)", name)
    if "trunk" in lengths_m and "shoulder_height" in lengths_m:
        raise ValueError("give the trunk or the shoulder_height, not both (one sets the other)")
    return dict(lengths_m)


def _rounded(length_m: float) -> float:
    """A length to 3 significant digits, for messages (a skeleton's 2.8000000000000007 m is 2.8 m)."""
    return float(f"{length_m:.3g}")


def _resized(old: Segment, length_m: float) -> Segment:
    """``old`` at another length: the same mass, centre of mass and radii scaled with the length."""
    k = length_m / old.length_m
    return Segment(old.name, length_m, old.mass_kg, old.com_from_proximal_m * k,
                   (old.radii_m[0] * k, old.radii_m[1] * k, old.radii_m[2] * k))


def body_mass_of(a: Anthropometry) -> float:
    """Mass of the whole body (both sides), kg."""
    paired = ("clavicle", "upper_arm", "forearm", "hand", "thigh", "shank", "foot")
    return sum(s.mass_kg * (2 if s.name in paired else 1) for s in a.segments.values())


def performer_anthropometry(height_m: float, mass_kg: float, skeleton_bvh: str | None = None,
                            skeleton_units: SkeletonUnits = "auto") -> Anthropometry:
    """The simulated drummer's body (the drummer scene's, and the End Sites ``batteur render`` gives performance.bvh):
    :func:`anthropometry` for ``height_m`` (metres) and ``mass_kg``, its limbs from a motion-capture skeleton's
    segment lengths when ``skeleton_bvh`` (a BVH path) is given, read in ``skeleton_units`` (:data:`SkeletonUnits`).
    ``ValueError`` naming the file for proportions the table cannot take."""
    from services.physics.bvh_motion import read_skeleton  # scipy and the BVH reader: only with a skeleton

    reading = read_skeleton(skeleton_bvh, skeleton_units) if skeleton_bvh else None
    lengths = None if reading is None else reading.lengths_m
    try:
        return anthropometry(height_m, mass_kg, lengths_m=lengths)
    except ValueError as exc:  # the skeleton's proportions: name the file they come from, and the joints
        if not lengths or reading is None:
            raise ValueError(str(exc)) from None
        where = reading.joints.get(exc.segment) if isinstance(exc, LengthError) else None
        measured = "" if where is None else f", measured from {where}"
        raise ValueError(f"skeleton_bvh {skeleton_bvh}: {exc}{measured}. {reading.joints_words}") from None
