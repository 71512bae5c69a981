"""Turns of a known angle (calib.inputs.turns): the turns file in CSV and JSON, imucal's Ferraris section list, and
every bad row refused with the row named."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from calib.inputs import TurnsError
from calib.inputs.turns import FERRARIS_ANGLE_DEG, FERRARIS_SIGMA_DEG, Turns, read_turns, turns_for_protocol

CLOCK = np.arange(0, 3000) / 100.0   # a 30-s recording at 100 Hz


def test_csv_rows_with_named_and_vector_axes(tmp_path):
    p = tmp_path / "turns.csv"
    p.write_text("# a user's file\nstart_s, end_s, axis, angle_deg, sigma_deg\n"
                 "2.0, 6.5, z, 360, 0.5\n10, 13, -x, 90, 1\n15, 18, 0 0.6 0.8, -180, 2\n")
    t = read_turns(p)
    assert len(t) == 3 and t.source == "turns.csv"
    assert t.turns[0].axis == (0.0, 0.0, 1.0) and t.turns[0].angle_rad == pytest.approx(2 * math.pi)
    assert t.turns[1].axis == (-1.0, 0.0, 0.0) and t.turns[1].sigma_rad == pytest.approx(math.radians(1.0))
    np.testing.assert_allclose(t.turns[2].axis, [0.0, 0.6, 0.8])
    assert t.sample_ranges(CLOCK) == [(200, 650), (1000, 1300), (1500, 1800)]
    assert Turns.from_dict(json.loads(json.dumps(t.to_dict()))) == t


def test_csv_axis_columns_and_json_forms(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("start_s,end_s,axis_x,axis_y,axis_z,angle_deg,sigma_deg\n1,2,0,0,2,45,1\n")
    assert read_turns(p).turns[0].axis == (0.0, 0.0, 1.0)
    rows = [{"start_s": 1, "end_s": 2, "axis": [0, 1, 0], "angle_deg": -90, "sigma_deg": 0.3, "label": "tip"}]
    for payload in (rows, {"turns": rows}):
        q = tmp_path / "t.json"
        q.write_text(json.dumps(payload))
        turn = read_turns(q).turns[0]
        assert (turn.axis, turn.label) == ((0.0, 1.0, 0.0), "tip")
        assert turn.angle_rad == pytest.approx(-math.pi / 2)


@pytest.mark.parametrize("body, message", [
    ("start_s,end_s,axis,angle_deg\n1,2,x,90\n", "no 'sigma_deg'"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n1,2,w,90,1\n", "axis 'w'"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n1,2,0 0 0,90,1\n", "non-zero vector"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n3,2,x,90,1\n", "not after start_s"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n1,2,x,ninety,1\n", "not a number"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n1,2,x,90,0\n", "must be above 0"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n1,4,x,90,1\n3,5,y,90,1\n", "overlap"),
    ("start_s,end_s,axis,angle_deg,sigma_deg\n", "no turns"),
    ("", "empty"),
    ("[1, 2]", "expected a list of turns"),
])
def test_bad_rows_are_refused_with_the_row_named(tmp_path, body, message):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    with pytest.raises(TurnsError, match=message) as err:
        read_turns(p)
    assert "Traceback" not in str(err.value)


def test_a_stretch_outside_the_recording_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("start_s,end_s,axis,angle_deg,sigma_deg\n25,40,z,360,1\n")
    with pytest.raises(TurnsError, match="not inside the recording"):
        read_turns(p).sample_ranges(CLOCK)
    with pytest.raises(TurnsError, match="no turns file"):
        read_turns(tmp_path / "missing.csv")


def test_ferraris_section_list_from_the_loader_and_from_beside_the_file(tmp_path):
    """imucal's list: x_rot, y_rot, z_rot as sample ranges, each −360° (imucal's clockwise expected_angle)."""
    segments = {"x_p": {"start": 10, "end": 200}, "x_rot": {"start": 300, "end": 620},
                "y_rot": {"start": 800, "end": 1100}, "z_rot": {"start": 1500, "end": 1800}}
    t = turns_for_protocol("ferraris", {"segments": segments}, CLOCK)
    assert [x.label for x in t.turns] == ["x_rot", "y_rot", "z_rot"]
    assert [x.axis for x in t.turns] == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    assert all(x.angle_rad == pytest.approx(math.radians(FERRARIS_ANGLE_DEG)) for x in t.turns)
    assert all(x.sigma_rad == pytest.approx(math.radians(FERRARIS_SIGMA_DEG)) for x in t.turns)
    assert t.sample_ranges(CLOCK) == [(300, 620), (800, 1100), (1500, 1800)]
    session = tmp_path / "walk.csv"
    session.write_text("")
    (tmp_path / "walk_list.json").write_text(json.dumps(segments))
    assert turns_for_protocol("ferraris", {}, CLOCK, session).turns == t.turns
    with pytest.raises(TurnsError, match="no other_list.json"):
        turns_for_protocol("ferraris", {}, CLOCK, tmp_path / "other.csv")
    with pytest.raises(TurnsError, match="no 'z_rot'"):
        turns_for_protocol("ferraris", {"segments": {k: v for k, v in segments.items() if k != "z_rot"}}, CLOCK)
    with pytest.raises(TurnsError, match="unknown protocol"):
        turns_for_protocol("tedaldi", {}, CLOCK)
