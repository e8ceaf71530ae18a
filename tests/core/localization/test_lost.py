"""Lost and found on exact synthetic frames (issue 28, item 3): after a slip the estimate is 0.5 m or 30° off, the
registrations keep disagreeing, the localizer gets lost after `lost_after_s`, frames not confirmed are dropped, and
the global search re-anchors where the view is unique (boxes at different depths) and gives up where it is not (a
single wall)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.localization import global_search, se2
from core.localization.gates import Verdict
from core.localization.lost import DROP, HOLD, INTEGRATE, LostWatch
from core.params import LocalizationParams
from core.types import LocalizationStatus
from tests.core.localization.synthetic import FLOOR, Rect, box, surface
from tests.core.localization.test_localizer import WALL, _drifted_frame, _localizer

PERIOD_S = 0.2
"""One registration per frame at the default 5 Hz."""
BOXES = [FLOOR, *box((1.8, 0.9), 0.6, 1), *box((2.5, -0.2), 0.6, 2), *box((1.7, -1.1), 0.6, 3)]
"""Three boxes ahead at different depths: every direction constrained, and after a slip every box disagrees (in the
corner of `test_localizer.py` a slip along the wall ahead leaves that wall agreeing, and the box alone that disagrees
is taken for a moved one: the correction is accepted, docs/decisions.md)."""


def _slipped(rects, slip: np.ndarray):
    """A localizer that was localized at t = 1.0 s, then fed frames whose pose is `slip` off (the true base stays at
    the origin) until it got lost; the next frame time."""
    loc = _localizer()
    frame, base = _drifted_frame(rects, np.zeros(3), t=1.0)
    assert loc.correct(frame, base, surface_of(rects)).verdict == Verdict.ACCEPTED
    loc.apply_due(10.0)
    t = 1.0
    while loc.status != LocalizationStatus.LOST:
        t += PERIOD_S
        assert t < 3.0, "the localizer should have got lost"
        frame, base = _drifted_frame(rects, slip, t=t)
        c = loc.correct(frame, base, surface_of(rects))
        assert c.verdict not in (Verdict.ACCEPTED, Verdict.SEARCHED), c
    return loc, t + PERIOD_S


def surface_of(rects):
    return surface(rects)


@pytest.mark.parametrize("slip", [np.array([0.0, 0.5, 0.0]), np.array([0.0, 0.0, math.radians(30.0)])],
                         ids=["sideways 0.5 m", "30 degrees"])
def test_a_slip_among_boxes_gets_lost_and_the_search_re_anchors_within_centimetres(slip):
    loc, t = _slipped(BOXES, slip)
    p = loc.params
    episode = loc.lost.episodes[-1]
    assert episode.lost_t - episode.refused_t >= p.lost_after_s - 1e-9
    # frames exposed since the last confirmed one are in doubt: dropped now that the localizer is lost
    assert loc.lost.fate(1.0, t) == INTEGRATE and loc.lost.fate(episode.refused_t - 0.05, t) == DROP
    assert "lost: searching" in (loc.health(t, 0.25).untrusted or "")
    frame, base = _drifted_frame(BOXES, slip, t=t)  # the first frame while lost: is the base at rest?
    c = loc.correct(frame, base, surface_of(BOXES))
    assert c.verdict == Verdict.SEARCHED and c.pose is None and not loc.lost.episodes[-1].searches
    frame, base = _drifted_frame(BOXES, slip, t=t + PERIOD_S)  # it did not move: search
    c = loc.correct(frame, base, surface_of(BOXES))
    assert c.verdict == Verdict.SEARCHED and c.pose is not None
    result = loc.lost.episodes[-1].searches[-1][1]
    assert result.unique and result.runner_up is not None and result.margin > p.search_margin, result
    assert loc.apply_due(c.apply_t - 0.01) is False and loc.status == LocalizationStatus.LOST  # due after the search
    loc.apply_due(c.apply_t)
    found = se2.compose(loc.world_from_odom, base)  # the base's pose by the re-anchored estimate (truth: 0)
    assert np.linalg.norm(found[:2]) < 0.05 and abs(math.degrees(found[2])) < 1.0, found
    assert loc.status == LocalizationStatus.LOCALIZED and not loc.lost.lost
    assert loc.lost.fate(c.apply_t - 0.05, c.apply_t) == DROP and loc.lost.fate(c.apply_t + 0.1, c.apply_t) == HOLD
    # found again: the next frame, posed by the re-anchored estimate, is accepted
    frame, _ = _drifted_frame(BOXES, found, t=c.apply_t + PERIOD_S)
    assert loc.correct(frame, found, surface_of(BOXES)).verdict == Verdict.ACCEPTED


WALL_SLIP = np.array([0.4, 0.0, 0.0])
"""Toward the wall, within the correspondence gate (`radius_max_m`, 0.5 m): the registrations find the wall 0.4 m off
its plane. (A slip of exactly 0.5 m put the wall's points at the gate: only floor points by the wall's foot were
judged, and whether their median passed `disagreement_m` was chance.)"""


def test_along_a_single_wall_the_search_is_not_unique_and_the_localizer_gives_up():
    loc, t = _slipped(WALL, WALL_SLIP)  # the registrations disagree across the wall
    p = loc.params
    frame, base = _drifted_frame(WALL, WALL_SLIP, t=t)
    loc.correct(frame, base, surface_of(WALL))  # the first frame while lost: the base at rest from the next one on
    t += PERIOD_S
    for k in range(p.search_tries):
        frame, base = _drifted_frame(WALL, WALL_SLIP, t=t)
        assert loc.correct(frame, base, surface_of(WALL)).verdict == Verdict.SEARCHED
        t += p.search_processing_s
        assert (loc.lost.failed is None) == (k < p.search_tries - 1)
    results = [r for _, r in loc.lost.episodes[-1].searches]
    assert len(results) == p.search_tries and not any(r.unique for r in results)
    assert all(r.runner_up is not None and r.best is not None and r.margin < p.search_margin for r in results)
    assert loc.lost.failed is not None and loc.lost.failed.startswith("lost localization")
    assert loc.apply_due(t + 10.0) is False and loc.status == LocalizationStatus.LOST


def test_the_grid_of_guesses_covers_plus_minus_one_metre_and_thirty_degrees():
    grid = global_search.offsets(_localizer().params)
    assert grid.shape == (9 * 9 * 7, 3)
    assert np.allclose(grid.min(axis=0), [-1.0, -1.0, -math.radians(30)])
    assert np.allclose(grid.max(axis=0), [1.0, 1.0, math.radians(30)])
    assert np.any(np.all(np.abs(grid) < 1e-12, axis=1)), "the estimate itself is a guess"


def test_a_view_the_reference_does_not_describe_is_no_jump_and_the_estimate_goes_on():
    """Lost among the boxes, then the frames show a wall the reference does not hold: no guess fits (a false alarm's
    case on E4's aisle, docs/decisions.md), so the localizer goes on from the estimate instead of faulting."""
    slip = np.array([0.0, 0.5, 0.0])
    loc, t = _slipped(BOXES, slip)
    before = loc.world_from_odom
    elsewhere = [FLOOR, Rect(0, 1.4, (-1.2, 0.0), (1.2, 1.5), 7)]  # a wall ahead the reference does not hold
    for k in range(2):  # the first frame only tells that the base is at rest
        frame, base = _drifted_frame(elsewhere, slip, t=t + k * PERIOD_S)
        c = loc.correct(frame, base, surface_of(BOXES))
    result = loc.lost.episodes[-1].searches[-1][1]
    assert result.best is not None and not result.fits and not result.unique, result  # measured: best 0.51
    assert loc.lost.failed is None and loc.lost.resume_t is not None
    loc.apply_due(loc.lost.resume_t)
    assert loc.status == LocalizationStatus.LOCALIZED and not loc.lost.lost
    np.testing.assert_allclose(loc.world_from_odom, before)  # not re-anchored
    assert c.pose is None


def test_a_small_chi2_refusal_says_the_filter_was_too_sure_and_is_no_jump():
    """Drift 8 cm off among the boxes with the filter sure to 2 cm: the registration is refused by χ², but its
    innovation is no jump (under `lost_jump_m`). P grows by the innovation, so the registrations are accepted again,
    and the localizer never gets lost; the frames up to the refusal are in doubt meanwhile."""
    loc = _localizer()
    loc.filter.P = np.diag([0.02**2, 0.02**2, math.radians(0.2) ** 2])  # sure of itself, yet 8 cm off
    loc.status = LocalizationStatus.LOCALIZED
    drift = np.array([0.08, 0.0, 0.0])
    frame, base = _drifted_frame(BOXES, drift, t=1.0)
    before = loc.filter.P.copy()
    c = loc.correct(frame, base, surface_of(BOXES))
    assert c.verdict == Verdict.CHI2 and not c.jump, c
    assert np.trace(loc.filter.P) > np.trace(before) + 0.05**2
    assert loc.lost.fate(1.0, 1.0) == HOLD and loc.lost.fate(1.0, 1.0 + loc.params.hold_max_s + 0.1) == DROP
    frame, base = _drifted_frame(BOXES, drift, t=1.0 + PERIOD_S)
    c = loc.correct(frame, base, surface_of(BOXES))
    assert c.verdict == Verdict.ACCEPTED and c.pose is not None, c  # the next frame passes, and corrects the drift
    assert np.hypot(*c.pose[:2]) < 0.02, c.pose
    assert loc.status != LocalizationStatus.LOST and not loc.lost.episodes


def test_an_object_the_search_found_no_jump_against_is_set_aside_and_the_view_does_not_get_lost_again():
    """E1's scene 8 (docs/decisions.md): the one object in view, mapped 12 cm off where the frames now see it (a stack
    mapped while the pose had drifted, seen from its other side), makes every registration inconsistent at a confident
    prediction that is right; the localizer gets lost, and the search finds the estimate fitting (no jump). That object
    is then set aside for `exclusion_s` (not handed to the map as change evidence), so the next frames have nothing to
    be inconsistent with: the view does not make the localizer lost again and again, as it did (seven times, then a
    search found no estimate fitting and the run faulted)."""
    seen = [FLOOR, *box((2.0, 0.0), 0.6, 4)]
    mapped = surface_of([FLOOR, *box((2.12, 0.0), 0.6, 4)])  # the map's object 4, 12 cm deeper than it is seen
    loc = _localizer()
    loc.filter.P = np.diag([0.01**2, 0.01**2, math.radians(0.1) ** 2])  # confident: judged at the prediction
    loc.status = LocalizationStatus.LOCALIZED
    t = 1.0
    while not loc.lost.lost:
        assert t < 3.0, "the premise: the view is inconsistent with the map and the localizer gets lost"
        frame, base = _drifted_frame(seen, np.zeros(3), t=t)
        c = loc.correct(frame, base, mapped)
        assert c.verdict == Verdict.INCONSISTENT and c.off == (4,), c
        t += PERIOD_S
    assert loc.lost.episodes[-1].suspects == (4,)
    for _ in range(2):  # the first frame only tells that the base is at rest
        frame, base = _drifted_frame(seen, np.zeros(3), t=t)
        loc.correct(frame, base, mapped)
        t += PERIOD_S
    result = loc.lost.episodes[-1].searches[-1][1]
    assert result.estimate_fits and loc.lost.resume_t is not None, result
    resume_t = loc.lost.resume_t
    loc.apply_due(resume_t)
    assert loc.status == LocalizationStatus.LOCALIZED and not loc.lost.lost
    verdicts = []
    t = max(t, resume_t)
    for _ in range(10):  # two seconds more of the same view
        t += PERIOD_S
        frame, base = _drifted_frame(seen, np.zeros(3), t=t)
        verdicts.append(loc.correct(frame, base, mapped).verdict)
    assert len(loc.lost.episodes) == 1 and not loc.lost.lost, verdicts
    assert Verdict.INCONSISTENT not in verdicts, verdicts
    assert loc.take_change_evidence() == (), "set aside, not reported as moved"


def test_a_chi2_refusal_from_one_object_alone_does_not_grow_the_filter_into_taking_it():
    """The anchored picks' lap start (docs/decisions.md): the one box in view moved 0.1 m, the pose right, the filter
    sure to 2 cm. The registration is pulled towards the box and refused by χ²; one object alone cannot say the filter
    was too sure (it may have moved), so P stays and the next frames are refused too: the estimate never follows the
    box (it had P grown by the pull and took the next frame: 0.1 m off here, 22 cm for a lap in the closed loop)."""
    seen = [FLOOR, *box((2.1, 0.0), 0.6, 4)]
    mapped = surface_of([FLOOR, *box((2.0, 0.0), 0.6, 4)])
    loc = _localizer()
    loc.filter.P = np.diag([0.02**2, 0.02**2, math.radians(0.2) ** 2])
    loc.status = LocalizationStatus.LOCALIZED
    before = loc.filter.P.copy()
    for k in range(3):
        frame, base = _drifted_frame(seen, np.zeros(3), t=1.0 + k * PERIOD_S)
        c = loc.correct(frame, base, mapped)
        assert c.verdict != Verdict.ACCEPTED, c
        loc.apply_due(10.0)
    assert np.allclose(loc.filter.P, before), loc.filter.P
    assert np.allclose(loc.world_from_odom, 0.0)


def test_a_still_box_that_fits_the_prediction_is_not_taken_for_the_moved_one():
    """Two of three boxes in view moved 0.1 m alike (as at the anchored picks' lap start) and drag the alignment
    off a right pose. Judged after the alignment, the still box looked off and was left out, the two moved ones
    taken, P grown by the refused pull and the next frame followed them. The still box fits the prediction and not
    the dragged pose, so it vouches for the prediction: it stays in the reference, a moved box that sits off the
    prediction is left out (handed to the map as change evidence), and the estimate stays within 3 cm over two
    frames. (The other moved box shows its front face and a side along the move: only 4 cm off at the median, it
    is not told apart and pulls a little.)"""
    still = box((2.5, -0.2), 0.6, 2)
    seen = [FLOOR, *box((1.9, 0.9), 0.6, 1), *still, *box((1.8, -1.1), 0.6, 3)]
    mapped = surface_of([FLOOR, *box((1.8, 0.9), 0.6, 1), *still, *box((1.7, -1.1), 0.6, 3)])
    loc = _localizer()
    loc.filter.P = np.diag([0.02**2, 0.02**2, math.radians(0.2) ** 2])
    loc.status = LocalizationStatus.LOCALIZED
    for k in range(2):
        frame, base = _drifted_frame(seen, np.zeros(3), t=1.0 + k * PERIOD_S)
        c = loc.correct(frame, base, mapped)
        assert 2 not in c.disagreeing and c.verdict != Verdict.INCONSISTENT, c
        loc.apply_due(10.0)
        assert np.hypot(*loc.world_from_odom[:2]) < 0.03, (k, c, loc.world_from_odom)
    assert 1 in loc.take_change_evidence()


def test_objects_that_fitted_a_moment_ago_and_now_pull_the_pose_have_moved():
    """The anchored picks' lap start on seed 4 with the frames-wait rule: both boxes in view moved alike (0.1 m along
    x here) right after an accepted registration had them fitting. Their pull is refused by χ², and as they agree
    with each other the view looked like a filter too sure of itself: P grew and the next frame took them (10 cm
    off here, 19 cm for the lap in the closed loop). The pose cannot have moved that far in 0.2 s without a slip
    (and the pull is under a jump), so they did: left out and handed to the map; the estimate stays."""
    before = [FLOOR, *box((1.8, 0.9), 0.6, 1), *box((2.3, -0.8), 0.6, 3)]
    after = [FLOOR, *box((1.9, 0.9), 0.6, 1), *box((2.4, -0.8), 0.6, 3)]
    mapped = surface_of(before)
    loc = _localizer()
    loc.status = LocalizationStatus.LOCALIZED
    frame, base = _drifted_frame(before, np.zeros(3), t=1.0)
    assert loc.correct(frame, base, mapped).verdict == Verdict.ACCEPTED
    loc.apply_due(10.0)
    loc.filter.P = np.diag([0.02**2, 0.02**2, math.radians(0.2) ** 2])
    for k in range(3):
        frame, base = _drifted_frame(after, np.zeros(3), t=1.2 + k * PERIOD_S)
        c = loc.correct(frame, base, mapped)
        assert c.verdict != Verdict.ACCEPTED or np.hypot(*c.pose[:2]) < 0.01, c
        loc.apply_due(10.0)
    assert np.hypot(*loc.world_from_odom[:2]) < 0.01, loc.world_from_odom
    assert set(loc.take_change_evidence()) == {1, 3}


def test_frames_wait_only_for_a_verdict_that_could_refuse_them():
    """A frame waits for the next registration at or after it only when that registration could find a jump: with no
    trusted surface in view (the latest verdict had nothing to judge by) it goes in at once; a degenerate or
    unconverged verdict outside a streak confirms the frames up to it (before, they waited `hold_max_s`, 1 s); in a
    streak they still wait."""
    watch = LostWatch(LocalizationParams())
    assert watch.fate(0.1, 0.15) == HOLD  # no verdict yet
    watch.observe(Verdict.NO_REFERENCE, 0.2, localized=False)
    assert watch.fate(0.3, 0.32) == INTEGRATE  # nothing trusted in view: no verdict could refuse it
    watch.observe(Verdict.ACCEPTED, 0.4, localized=True)
    assert watch.fate(0.5, 0.52) == HOLD  # trusted surface in view: the next registration may find a jump
    watch.observe(Verdict.DEGENERATE, 0.6, localized=True)
    assert watch.fate(0.55, 0.62) == INTEGRATE and watch.fate(0.65, 0.7) == HOLD
    watch.observe(Verdict.INCONSISTENT, 0.8, localized=True)  # a streak starts
    watch.observe(Verdict.DEGENERATE, 1.0, localized=True)
    assert watch.fate(0.9, 1.02) == HOLD
    watch.observe(Verdict.NO_REFERENCE, 1.2, localized=True)  # ends the streak: nothing to judge since
    assert watch.fate(1.3, 1.31) == INTEGRATE


def _lost_in(rects, error: np.ndarray, mapped=None, off: tuple[int, ...] = (1,)):
    """A localizer made lost by a streak of inconsistent registrations that found `off` off their surfaces (as a moved
    box or a mapped object off its surface makes), then fed frames of `rects` (reference: `mapped`, else `rects`) from
    the origin, posed `error` off, until its first search; that search's result."""
    loc = _localizer()
    loc.status = LocalizationStatus.LOCALIZED
    t = 1.0
    while not loc.lost.observe(Verdict.INCONSISTENT, t, True, off=off):
        t += PERIOD_S
        assert t < 3.0
    for _ in range(2):  # the first frame only tells that the base is at rest
        t += PERIOD_S
        frame, base = _drifted_frame(rects, error, t=t)
        loc.correct(frame, base, surface_of(mapped or rects))
    return loc, loc.lost.episodes[-1].searches[-1][1]


def test_an_ambiguous_search_is_tried_again_without_the_objects_found_off_and_the_estimate_goes_on():
    """E4's aisle with localization on (docs/decisions.md): a box moved unseen, the map still holding alike boxes at
    old places on either side of it, made the searches find fits of 0.98-0.99 at distinct poses (the wall along y fits
    every shift) while the estimate was right and fitted worse (measured with the map as it is: not unique, the
    estimate not fitting), and the run faulted. Without the objects the streak found off,
    the estimate fits: the run goes on from it, not re-anchored, and those objects are set aside."""
    seen = [FLOOR, Rect(0, 2.2, (-3.0, 0.0), (3.0, 1.5), 1), *box((1.2, 0.3), 0.6, 2)]
    mapped = [FLOOR, Rect(0, 2.2, (-3.0, 0.0), (3.0, 1.5), 1), *box((1.2, -0.6), 0.6, 2), *box((1.2, 1.2), 0.6, 3)]
    loc, result = _lost_in(seen, np.zeros(3), mapped, off=(2, 3))  # the streak the moved box made
    before = loc.world_from_odom  # a search moves nothing before its outcome is applied
    assert result.estimate_fits, result
    assert loc.lost.failed is None and loc.lost.resume_t is not None
    loc.apply_due(loc.lost.resume_t)
    assert loc.status == LocalizationStatus.LOCALIZED and not loc.lost.lost
    np.testing.assert_allclose(loc.world_from_odom, before)
    assert {2, 3} <= set(loc._excluded)


CORRIDOR = [FLOOR, Rect(1, 1.0, (-3.0, 0.0), (8.0, 1.5), 1), Rect(1, -1.0, (-3.0, 0.0), (8.0, 1.5), 2)]
"""Two walls along the heading, 2 m apart: y and yaw constrained, x (along the corridor) not."""


MAPPED_AHEAD = [FLOOR, Rect(1, 1.0, (2.5, 0.0), (8.0, 1.5), 1), Rect(1, -1.0, (2.5, 0.0), (8.0, 1.5), 2)]
"""The corridor as a reference holds it: only from 2.5 m ahead (the walls' near part left out, as an object set aside
leaves it). At the estimate the near points fit nothing, so guesses farther along fit better before registration."""


def test_in_a_corridor_fits_along_it_through_the_estimate_are_no_jump_and_the_estimate_goes_on():
    """The aisle at a 20 Hz base camera (docs/decisions.md): the estimate 11 cm off, an object judged off made the
    localizer lost, and every search found fits along the aisle, 0.6-0.8 m apart, all at the estimate's heading and
    across the aisle where the estimate is; five of them faulted the run. Along a corridor no view tells where the base
    is, so no re-anchoring can either: the fits on one line through the estimate say it agrees where the view can tell,
    and the run goes on from it (not re-anchored)."""
    loc, result = _lost_in(CORRIDOR, np.array([0.03, 0.0, 0.0]), MAPPED_AHEAD)
    assert not result.unique and result.runner_up is not None, result  # the premise: fits all along the corridor,
    assert result.best.pose[0] > 0.5, result  # the best well ahead of the estimate (measured: 1.04 m; before
    # registration the estimate did not fit as well as the best guess, and the run faulted)
    assert result.corridor and result.estimate_fits, result
    assert loc.lost.failed is None and loc.lost.resume_t is not None
    before = loc.world_from_odom
    loc.apply_due(loc.lost.resume_t)
    assert loc.status == LocalizationStatus.LOCALIZED and not loc.lost.lost
    np.testing.assert_allclose(loc.world_from_odom, before)


@pytest.mark.parametrize("error", [np.array([0.0, 0.4, 0.0]), np.array([0.0, 0.0, math.radians(15.0)])],
                         ids=["across 0.4 m", "15 degrees"])
def test_in_a_corridor_an_estimate_off_across_it_or_in_heading_is_not_on_the_line_of_fits(error):
    """The other side of the corridor rule: after a slip across the corridor or in heading the fits lie along the
    corridor where the base is, not through the estimate: no way out, the searches go on (and fault if none is
    unique)."""
    loc, result = _lost_in(CORRIDOR, error, MAPPED_AHEAD)
    assert not result.corridor and not result.estimate_fits, result
    assert loc.lost.resume_t is None or result.unique


def test_a_base_at_rest_whose_heading_is_reported_across_pi_is_at_rest_for_a_search():
    """A backend that reports its heading wrapped to (-π, π]: at rest by a heading of π - 0.001 then -π + 0.001."""
    watch = LostWatch(LocalizationParams(enabled=True))
    watch.lost = True
    assert not watch.wants_search(1.0, np.array([1.0, 2.0, math.pi - 0.001]))  # the first frame: nothing to compare
    assert watch.wants_search(1.2, np.array([1.0, 2.0, -math.pi + 0.001]))
    assert not watch.wants_search(1.4, np.array([1.0, 2.0, -math.pi + 0.05]))  # turning: not at rest
