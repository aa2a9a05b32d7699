"""Per-target verdicts: inside the band reproduced, outside it on the better side beats the
paper, on the worse side missed; the experiment's one line follows from them."""

import math

import pytest

from orchestrator.experiments import verdicts as vd


def test_outcome_is_the_side_of_the_band():
    assert vd.about("roll", 30, 31.0, better="higher")["outcome"] == vd.REPRODUCED
    assert vd.about("roll", 30, 59.4, better="higher")["outcome"] == vd.BEATS
    assert vd.about("roll", 30, 20.0, better="higher")["outcome"] == vd.MISSED
    # the band's ends are inside it
    assert vd.about("roll", 30, 35.0, better="higher")["outcome"] == vd.REPRODUCED
    assert vd.between("all", 50, 80, 80.0 + 1e-9, better="higher")["outcome"] == vd.BEATS
    # no better side: outside is missed either way
    assert vd.about("f", 45, 60.0, "Hz")["outcome"] == vd.MISSED
    assert vd.about("f", 45, 30.0, "Hz")["outcome"] == vd.MISSED
    # open bands: at least is better higher, below better lower
    assert vd.at_least("pitch", 50, 10.3)["outcome"] == vd.MISSED
    assert vd.at_least("pitch", 50, 90.0)["outcome"] == vd.REPRODUCED
    assert vd.below("stroke", 5, 6.0, "um")["outcome"] == vd.MISSED
    assert vd.below("stroke", 5, 0.04, "um")["outcome"] == vd.REPRODUCED
    for ours in (None, math.nan):
        v = vd.about("roll", 30, ours, better="higher")
        assert v["outcome"] == vd.NOT_MEASURED and v["reproduced"] is False


def test_reproduced_stays_true_only_inside_the_band():
    v = vd.about("roll", 30, 59.4, better="higher")
    assert v["reproduced"] is False and v["better"] == "higher"
    assert vd.all_reproduced([v]) is False


def test_overall_line():
    rep = vd.about("yaw", 60, 62.0, better="higher")
    beat = vd.about("roll", 30, 59.4, better="higher")
    miss = vd.at_least("pitch", 50, 10.3)
    assert vd.overall([rep]) == "reproduced"
    assert vd.overall([rep, beat]) == ("reproduced or beaten on every target (beats the "
                                       "paper on: roll)")
    assert vd.overall([rep, beat, miss]) == "missed: pitch (beats the paper on: roll)"
    assert vd.overall([miss]) == "missed: pitch"
    assert vd.outcome_words(beat) == "roll: 59.4 % (paper about 30 %, beats the paper)"


def test_an_unknown_side_is_refused():
    with pytest.raises(ValueError, match="better='up'"):
        vd.about("roll", 30, 31.0, better="up")


def test_inconsistencies_name_a_reproduced_flag_its_number_contradicts():
    ok = [vd.between("all", 50, 80, 60.4, better="higher"),
          vd.at_least("pitch", 50, 10.3), vd.below("stroke", 5, 0.04, "um")]
    assert vd.inconsistencies({"verdicts": ok, "reproduced": False}) == []
    # a flag set by hand against the number, and the experiment's flag against its verdicts
    forged = dict(ok[1], reproduced=True)
    msgs = vd.inconsistencies({"verdicts": [ok[0], forged], "reproduced": True})
    assert len(msgs) == 1 and msgs[0].startswith("pitch: ours 10.3 is outside")
    msgs = vd.inconsistencies({"verdicts": [ok[0], ok[2]], "reproduced": False})
    assert msgs == ["the experiment's reproduced is False but its verdicts say True"]
    # an open end is None in the JSON; a number on the open side is inside
    assert vd.inconsistencies({"verdicts": [vd.at_least("p", 50, 1e6)], "reproduced": True}) == []
    assert vd.inconsistencies({"note": "no verdicts"}) == []
