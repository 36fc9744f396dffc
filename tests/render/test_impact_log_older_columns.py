"""impacts.csv gained a column on 8 Dec (``openness``, the Impact's appended field: a hi-hat stroke's openness as
heard, -1 elsewhere). A render's impacts.csv from before it (11 columns) is still read, each impact with openness
-1, so ``batteur evaluate`` and ``compare`` take an older render folder (before: refused, ``expected columns``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.impact_log import COLUMNS, read_impacts_csv, write_impacts_csv
from common.messages import Impact

OLDER = "seq,time,instrument,zone,r,theta,velocity,impulse,peak_force,duration,part"
ROW = "1,1.50199997,hihat,closed,0.583541393,0.0013345019,2.94916248,0.0697254688,29.3305836,0.004,right_stick_tip"


def test_the_columns_end_with_openness() -> None:
    assert COLUMNS == [*OLDER.split(","), "openness"]


def test_an_older_render_s_impacts_csv_is_read_with_openness_minus_one(tmp_path: Path) -> None:
    path = tmp_path / "impacts.csv"
    path.write_text(f"{OLDER}\r\n{ROW}\r\n", encoding="utf-8")
    (impact,) = read_impacts_csv(path)
    assert impact.instrument == "hihat" and impact.zone == "closed" and impact.openness == -1.0
    assert impact.part == "right_stick_tip" and impact.duration == pytest.approx(0.004)


def test_openness_is_written_and_read_back(tmp_path: Path) -> None:
    hat = Impact(seq=3, time=2.5, instrument="hihat", zone="half", r=0.6, theta=0.0, velocity=3.0, impulse=0.07,
                 peak_force=30.0, duration=0.004, part="right_stick_tip", openness=0.75)
    snare = hat.model_copy(update={"seq": 4, "instrument": "snare", "zone": "centre", "openness": -1.0})
    path = tmp_path / "impacts.csv"
    write_impacts_csv([hat, snare], path)
    assert path.read_text(encoding="utf-8").splitlines()[0] == ",".join(COLUMNS)
    assert read_impacts_csv(path) == [hat, snare]


def test_a_file_with_other_columns_is_still_refused(tmp_path: Path) -> None:
    path = tmp_path / "impacts.csv"
    path.write_text("seq,time,instrument,zone\r\n1,1.5,hihat,closed\r\n", encoding="utf-8")
    with pytest.raises(ValueError, match="expected columns"):
        read_impacts_csv(path)
