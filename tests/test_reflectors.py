"""viewer/reflectors.py: which planar reflectors get a mirror pass, and why the others do not."""
import math

import numpy as np
import pytest
from conftest import quad

from glint.core.scene import Object
from glint.viewer.camera import ViewCamera, in_frustum
from glint.viewer.mirror_camera import MirrorCamera
from glint.viewer.reflectors import (
    OcclusionResults,
    Reflector,
    SkipReason,
    plan_mirror_passes,
    projected_area,
    reflectors_of,
)

ASPECT = 16 / 9


def floor_patch(name, x0, x1, z0, z1, y=0.0, normal=(0, 1, 0)):
    return Reflector(name, ((x0 + x1) / 2, y, (z0 + z1) / 2), normal,
                     [(x0, y, z0), (x1, y, z1)], area=(x1 - x0) * (z1 - z0))


def wall_patch(name, x0, x1, y0, y1, z, normal=(0, 0, 1)):
    return Reflector(name, ((x0 + x1) / 2, (y0 + y1) / 2, z), normal,
                     [(x0, y0, z), (x1, y1, z)], area=(x1 - x0) * (y1 - y0))


@pytest.fixture
def camera():
    return ViewCamera.look_at((0, 1.6, 3), (0, 0.6, -1), yfov=math.radians(60), znear=0.05, zfar=100)


def reasons(plan):
    return {s.reflector.name: s.reason for s in plan.skipped}


def test_visible_floor_gets_a_pass_with_its_mirror_camera(camera):
    plan = plan_mirror_passes([floor_patch("floor", -2, 2, -3, 2)], camera, ASPECT)
    assert len(plan.passes) == 1 and not plan.skipped
    p = plan.passes[0]
    assert p.names == ["floor"] and isinstance(p.camera, MirrorCamera)
    assert np.allclose(p.normal, (0, 1, 0)) and abs(p.point[1]) < 1e-12
    assert np.allclose(p.camera.eye, (0, -1.6, 3))
    assert 0 < p.screen_area <= 1 and p.distance == pytest.approx(math.hypot(1.6, 1.0))
    assert [r.name for r in plan.queries] == ["floor"]
    assert plan.pass_for("floor") == 0 and plan.pass_for("nope") is None


def test_skips_with_the_right_reason(camera):
    refl = [
        floor_patch("floor", -2, 2, -3, 2),
        floor_patch("behind camera", -1, 1, 5, 8),  # the camera at z = 3 looks towards -z
        floor_patch("far left", 40, 45, -5, -3),  # off to the side
        floor_patch("below horizon? no: beyond far", -1, 1, -300, -200),
        wall_patch("mirror back", -0.5, 0.5, 0.5, 1.5, -2.0, normal=(0, 0, -1)),  # faces away
        floor_patch("ceiling from above", -1, 1, -2, 0, y=2.0),  # eye (y 1.6) is below it
        floor_patch("ceiling", -1, 1, -2, 0, y=2.0, normal=(0, -1, 0)),  # faces the eye: runs
        wall_patch("edge-on", -1, 1, 1.0, 2.0, 3.0),  # its plane z = 3 contains the eye
    ]
    plan = plan_mirror_passes(refl, camera, ASPECT)
    assert reasons(plan) == {
        "behind camera": SkipReason.OUTSIDE_FRUSTUM,
        "far left": SkipReason.OUTSIDE_FRUSTUM,
        "below horizon? no: beyond far": SkipReason.OUTSIDE_FRUSTUM,
        "mirror back": SkipReason.BACK_FACING,
        "ceiling from above": SkipReason.BACK_FACING,
        "edge-on": SkipReason.BACK_FACING,
    }
    assert sorted(n for p in plan.passes for n in p.names) == ["ceiling", "floor"]
    stats = plan.stats()
    assert stats["passes_run"] == 2 and stats["reflectors_in_passes"] == 2
    assert stats["skipped"] == {"outside frustum": 3, "seen from behind": 3, "occluded": 0, "over budget": 0}
    text = plan.summary()
    assert "2 run" in text and "3 outside frustum" in text and "3 seen from behind" in text


def test_coplanar_reflectors_share_one_pass(camera):
    tiles = [floor_patch(f"tile {i}", x, x + 1, -2, 1) for i, x in enumerate((-2, -1, 0, 1))]
    table = floor_patch("table", -0.5, 0.5, -1.5, -0.5, y=0.75)
    plan = plan_mirror_passes(tiles + [table], camera, ASPECT, budget=4)
    assert len(plan.passes) == 2
    assert sorted(plan.passes[0].names) == [t.name for t in tiles]  # larger on screen: first
    assert plan.passes[1].names == ["table"]
    assert all(plan.pass_for(t.name) == 0 for t in tiles)


def test_budget_keeps_the_largest_on_screen(camera):
    refl = [
        floor_patch("small far", -0.3, 0.3, -8, -7.5, y=0.4),  # a far table top
        floor_patch("big near", -2, 2, -3, 2),
        wall_patch("wall mirror", -0.8, 0.8, 0.5, 1.8, -2.0),
    ]
    plan = plan_mirror_passes(refl, camera, ASPECT, budget=1)
    assert [p.names for p in plan.passes] == [["big near"]]
    assert reasons(plan) == {"small far": SkipReason.OVER_BUDGET, "wall mirror": SkipReason.OVER_BUDGET}
    assert plan.stats()["passes_over_budget"] == 2
    plan = plan_mirror_passes(refl, camera, ASPECT, budget=2)
    assert [p.names for p in plan.passes] == [["big near"], ["wall mirror"]]
    assert reasons(plan) == {"small far": SkipReason.OVER_BUDGET}
    plan = plan_mirror_passes(refl, camera, ASPECT, budget=0)
    assert not plan.passes and len(plan.skipped) == 3


def test_budget_tie_on_screen_goes_to_the_nearest():
    # Looking straight down: a wide table top and the floor both fill the screen.
    cam = ViewCamera(eye=(0, 1.6, 0), forward=(0, -1, 0), up=(0, 0, -1), yfov=math.radians(50))
    refl = [floor_patch("floor", -10, 10, -10, 10), floor_patch("table", -10, 10, -10, 10, y=0.5)]
    plan = plan_mirror_passes(refl, cam, ASPECT, budget=1)
    assert plan.passes[0].screen_area == pytest.approx(1.0)
    assert plan.passes[0].names == ["table"] and plan.passes[0].distance == pytest.approx(1.1)
    assert reasons(plan) == {"floor": SkipReason.OVER_BUDGET}


def test_occlusion_results_skip_hidden_reflectors(camera):
    refl = [floor_patch("floor", -2, 2, -3, 2), wall_patch("wall mirror", -0.8, 0.8, 0.5, 1.8, -2.0)]
    occ = OcclusionResults(max_age=2)
    occ.record("wall mirror", 0, frame=10)
    occ.record("floor", 1234, frame=10)
    plan = plan_mirror_passes(refl, camera, ASPECT, occlusion=occ, frame=11)
    assert reasons(plan) == {"wall mirror": SkipReason.OCCLUDED}
    assert [p.names for p in plan.passes] == [["floor"]]
    # Hidden reflectors are still queried so they can come back.
    assert sorted(r.name for r in plan.queries) == ["floor", "wall mirror"]
    assert plan.stats()["skipped"]["occluded"] == 1
    # A stale zero is not trusted; a fresh positive result brings it back.
    assert len(plan_mirror_passes(refl, camera, ASPECT, occlusion=occ, frame=13).passes) == 2
    occ.record("wall mirror", True, frame=11)
    assert len(plan_mirror_passes(refl, camera, ASPECT, occlusion=occ, frame=12).passes) == 2
    occ.record("wall mirror", 0, frame=12)
    occ.forget("wall mirror")
    assert not occ.occluded("wall mirror", 12)


def test_budget_is_spent_on_visible_reflectors_only(camera):
    refl = [floor_patch("floor", -2, 2, -3, 2), wall_patch("wall mirror", -0.8, 0.8, 0.5, 1.8, -2.0)]
    occ = OcclusionResults()
    occ.record("floor", 0, frame=0)
    plan = plan_mirror_passes(refl, camera, ASPECT, budget=1, occlusion=occ, frame=1)
    assert [p.names for p in plan.passes] == [["wall mirror"]]


def test_frustum_helpers(camera):
    vp = camera.view_projection(ASPECT)
    assert in_frustum(np.array([[-0.1, 0.5, -1.1], [0.1, 0.7, -0.9]]), vp)
    assert not in_frustum(np.array([[-0.1, 0.5, 4], [0.1, 0.7, 5]]), vp)  # behind
    # Screen area: a box filling the view; a box straddling the eye plane is clipped, not inverted.
    assert projected_area(np.array([[-50, -50, -60], [50, 50, -40]]), vp) == pytest.approx(1.0)
    straddle = projected_area(np.array([[-0.2, 0.0, -1.0], [0.2, 0.1, 6.0]]), vp)
    assert 0 < straddle <= 1
    assert projected_area(np.array([[-0.1, 0.5, 4], [0.1, 0.7, 5]]), vp) == 0.0


def test_reflector_from_a_scene_object():
    p, i = quad((0, 0, 0), (1, 0, 0), (0, 0, -1))  # faces +Y
    obj = Object("Floor", p, np.tile(np.float32([0, 1, 0]), (4, 1)), i, 0, role="planar")
    other = Object("Box", p + (0, 1, 0), np.tile(np.float32([0, 1, 0]), (4, 1)), i, 0, role="curved")
    (r,) = reflectors_of([obj, other])
    assert r.name == "Floor" and np.allclose(r.normal, (0, 1, 0)) and abs(r.point[1]) < 1e-12
    assert np.allclose(r.bounds, [[-1, 0, -1], [1, 0, 1]]) and r.area == pytest.approx(4.0)
