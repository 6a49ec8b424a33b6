"""Marker labels matched between files: marker-set aliases, a user mapping, unknown labels."""

from __future__ import annotations

import pytest

from conftest import real_data_path
from saddlescope.core.errors import InputError
from saddlescope.io.mocap import read_mocap
from saddlescope.io.mocap.labels import landmark_key, match_labels, parse_label_map


@pytest.mark.parametrize("label", ["RASI", "R.ASIS", "RightASIS", "R_ASIS", "r asis", "ASIS_Right", "Right-ASIS"])
def test_one_landmark_under_every_marker_set_name(label):
    assert landmark_key(label) == "R:ASI"


def test_sides_midline_descriptions_and_unknown_labels():
    assert landmark_key("LKNE") == landmark_key("L.Knee") == "L:KNE"
    assert landmark_key("RKNE (R.Knee.Medial)") == landmark_key("R.Knee.Medial") == "R:KNM"
    assert landmark_key("V.Sacral") == landmark_key("SACR") == "SACR"
    assert landmark_key("IJ") == landmark_key("CLAV") and landmark_key("PX") == landmark_key("STRN")
    assert landmark_key("RSHA") == landmark_key("RTIB")  # Plug-in-Gait's shank wand, two spellings
    assert landmark_key("Channel101") == "=channel101" != landmark_key("Channel102")


def test_match_by_name_then_alias_then_user_map():
    m = match_labels(["RASI", "LASI", "C7", "FOO"], ["L.ASIS", "R.ASIS", "C7", "BAR"])
    assert m.pairs == (("RASI", "R.ASIS"), ("LASI", "L.ASIS"), ("C7", "C7"))
    assert m.by_alias == (("RASI", "R.ASIS"), ("LASI", "L.ASIS"))
    assert m.unmatched_a == ("FOO",) and m.unmatched_b == ("BAR",)
    m = match_labels(["RASI", "FOO"], ["R.ASIS", "BAR"], user_map={"FOO": "BAR"})
    assert m.pairs == (("RASI", "R.ASIS"), ("FOO", "BAR")) and m.unmatched_a == ()
    # The user's map wins over an alias: RASI is told to be the other file's L.ASIS.
    m = match_labels(["RASI"], ["R.ASIS", "L.ASIS"], user_map={"RASI": "L.ASIS"})
    assert m.pairs == (("RASI", "L.ASIS"),)


def test_bad_maps_and_labels_are_clear_errors():
    assert parse_label_map(["A=B", " C = D "]) == {"A": "B", "C": "D"}
    with pytest.raises(InputError, match="LABEL_IN_A=LABEL_IN_B"):
        parse_label_map(["AB"])
    with pytest.raises(InputError, match="first file has no marker labelled 'X'"):
        match_labels(["A"], ["B"], user_map={"X": "B"})
    with pytest.raises(InputError, match="second file has no marker labelled 'Y'"):
        match_labels(["A"], ["B"], user_map={"A": "Y"})
    with pytest.raises(InputError, match="first file has no marker labelled Z"):
        match_labels(["A"], ["B"], wanted=["Z"])


@pytest.mark.realdata
def test_gait_c3d_and_trc_labels_all_match():
    c3d = read_mocap(real_data_path("c3d", "Gait.c3d"))
    trc = read_mocap(real_data_path("c3d", "Gait.trc"))
    m = match_labels(c3d.labels, trc.labels)
    assert len(m.pairs) == 33 and m.unmatched_a == ()
    assert ("RASI", "R.ASIS") in m.pairs and ("RKNE (R.Knee.Medial)", "R.Knee.Medial") in m.pairs
    # the TRC's 33 unnamed columns (M034 ...) have no partner
    assert all(s.startswith("M0") for s in m.unmatched_b)
    pig = read_mocap(real_data_path("c3d", "PiG_Motion3_FF.c3d"))
    m = match_labels(c3d.labels, pig.labels)
    assert ("RSHA", "RTIB") in m.pairs and ("LASI", "LASI") in m.pairs and len(m.pairs) == 14
