"""A BVH that cannot be read is named with the problem and where it is: the line (1-based) of a missing or extra
``}``, of a CHANNELS count its names do not fill, of a bad number; a motion value by its frame (counted from 1, as
the file's motion lines), line, channel and joint (the messages had no line and counted frames from 0)."""

from __future__ import annotations

import re

import pytest

from common.gesture.bvh import BvhError, parse_bvh

GOOD = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.03
0 0 0 0 0 0 0 0 0
0 0 0 0 0 0 1 2 3
0 0 0 0 0 0 4 5 6
"""


def _edit(line: int, new: str | None) -> str:
    """GOOD with its 1-based ``line`` replaced (None: removed)."""
    lines = GOOD.splitlines()
    if new is None:
        del lines[line - 1]
    else:
        lines[line - 1] = new
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("text", "says"), [
    (_edit(13, None), "line 15: MOTION before the hierarchy is closed: a '}' is missing; still open: Hips (line 2)"),
    (_edit(13, "    }\n    }"), "line 16: expected 'MOTION', found '}' (the root's block closed at line 15: an extra "
                              "'}' above?)"),
    (_edit(9, "    CHANNELS 4 Zrotation Xrotation Yrotation"),
     "line 10: joint Spine: 'End' is not a channel name: its CHANNELS 4 (line 9) names 3 (Zrotation Xrotation "
     "Yrotation); valid names: Xposition Yposition Zposition Xrotation Yrotation Zrotation"),
    (_edit(8, "    OFFSET 0 abc 0"), "line 8: expected a number, found 'abc'"),
    (_edit(21, "0 0 0 0 0 0 4 nan 6"),
     "line 21: motion frame 3 of 3 (frames counted from 1), channel 8 (Spine Xrotation) holds a value that is not "
     "finite ('nan')"),
    (_edit(20, "0 0 0 0 0 0 1 x 3"), "line 20: motion frame 2 of 3, channel 8 (Spine Xrotation): 'x' is not a number"),
    (_edit(20, "0 0 0 0 0 0 1 2"), "truncated motion: 3 frames x 9 channels announced, 26 values found; line 20 "
                                   "holds 8 values, not 9"),
    (_edit(17, "Frames: x"), "line 17: expected a whole number, found 'x'"),
])
def test_a_broken_bvh_says_where(text: str, says: str) -> None:
    assert parse_bvh(GOOD, "ok.bvh").motion.shape == (3, 9)
    with pytest.raises(BvhError, match=f"^bad\\.bvh: {re.escape(says)}$"):
        parse_bvh(text, "bad.bvh")


@pytest.mark.parametrize("text", ["", "  \n\n"])
def test_an_empty_file_is_said_to_be_empty(text: str) -> None:
    """An empty file was "file ended early (truncated hierarchy or motion)", as if part of it had been read."""
    with pytest.raises(BvhError, match=r"^empty\.bvh: empty file \(a BVH starts with HIERARCHY\)$"):
        parse_bvh(text, "empty.bvh")
    with pytest.raises(BvhError, match="file ended early"):  # a truncated one still says so
        parse_bvh("HIERARCHY\nROOT Hips\n{\n", "cut.bvh")


def test_bad_channel_names_are_listed_with_the_valid_ones() -> None:
    """``CHANNELS 3 Zrot Xrot Yrot`` said "its CHANNELS 3 (line 9) names 0": neither the names found nor the
    valid ones."""
    with pytest.raises(BvhError) as caught:
        parse_bvh(_edit(9, "    CHANNELS 3 Zrot Xrotation Yrot"), "bad.bvh")
    assert str(caught.value) == (
        "bad.bvh: line 9: joint Spine: its CHANNELS 3 (line 9) names Zrot Xrotation Yrot: 'Zrot', 'Yrot' are not "
        "channel names; valid names: Xposition Yposition Zposition Xrotation Yrotation Zrotation")
    with pytest.raises(BvhError, match=r": 'Zrot' is not a channel name; valid names: Xposition "):
        parse_bvh(_edit(9, "    CHANNELS 3 Zrot Xrotation Yrotation"), "bad.bvh")
