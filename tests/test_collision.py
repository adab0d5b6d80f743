"""Walking into a wall (viewer/collision.py): the eye stops RADIUS short of it and slides along it,
instead of passing through it into the black outside of the room.

The geometry is written here: a 2 x 2 m wall in the plane z = -1 (normal +z) and the walker at
z = 0 facing -z; expected positions follow from the plane, not from the collider's code."""
from __future__ import annotations

import math

import numpy as np
import pytest

from glint.viewer.camera import ViewCamera
from glint.viewer.collision import RADIUS, Collider
from glint.viewer.controls import WalkControls

WALL = np.array([[[-1, 0, -1], [1, 0, -1], [1, 2, -1]], [[-1, 0, -1], [1, 2, -1], [-1, 2, -1]]], float)


def walker(collide=True) -> WalkControls:
    c = WalkControls([], [], ViewCamera(eye=(0.0, 1.0, 0.0), forward=(0.0, 0.0, -1.0)), speed=1.0)
    if collide:
        c.collide = Collider(WALL).move
    return c


def walk(c: WalkControls, keys, seconds: float, dt: float = 0.05):
    for k in keys:
        c.key_press(k)
    for _ in range(round(seconds / dt)):
        c.update(dt)
    for k in keys:
        c.key_release(k)
    return np.asarray(c.pose.eye)


def test_walking_into_a_wall_stops_short_of_it_and_slides_along():
    """Forward for 3 s at 1 m/s: the eye stops at z = -1 + RADIUS (within 1 mm), never beyond;
    forward and right together (45 degrees into the wall) it slides right along the wall at the
    same distance; backing off works. Without a collider the same walk ends at z = -3, behind
    the wall (checked below)."""
    c = walker()
    eye = walk(c, ["w"], 3.0)
    assert eye[2] == pytest.approx(-1 + RADIUS, abs=1e-3) and eye[2] >= -1 + RADIUS - 1e-9
    x0 = eye[0]
    eye = walk(c, ["w", "d"], 1.0)  # 1 m at 45 degrees: about 0.71 m along the wall
    assert eye[2] == pytest.approx(-1 + RADIUS, abs=1e-3)
    assert eye[0] - x0 == pytest.approx(1 / math.sqrt(2), abs=0.02)
    eye = walk(c, ["s"], 0.5)
    assert eye[2] == pytest.approx(-1 + RADIUS + 0.5, abs=1e-3)
    free = walk(walker(collide=False), ["w"], 3.0)
    assert free[2] == pytest.approx(-3.0)  # without a collider the same walk goes through


def test_the_other_side_and_the_edges():
    """Behind the wall (z = -2, facing +z) the wall stops the walker on its other side too; past
    its edge (x = 1.5) nothing stops it."""
    c = WalkControls([], [], ViewCamera(eye=(0.0, 1.0, -2.0), forward=(0.0, 0.0, 1.0)), speed=1.0)
    c.collide = Collider(WALL).move
    assert walk(c, ["w"], 3.0)[2] == pytest.approx(-1 - RADIUS, abs=1e-3)
    c = WalkControls([], [], ViewCamera(eye=(1.5, 1.0, 0.0), forward=(0.0, 0.0, -1.0)), speed=1.0)
    c.collide = Collider(WALL).move
    assert walk(c, ["w"], 3.0)[2] == pytest.approx(-3.0)


def test_the_window_stops_the_walker_above_the_floor(ctx, tmp_path):
    """In the window (tests/test_panel.py's floor, single-sided, seen from above): 3 s of Q (down,
    1 m/s) from 1 m up leaves the eye RADIUS above the floor and the frame shows the floor, not
    black. Deliberate bug this catches (tried): ViewerWindow not giving the controls the bake's
    collider -> the eye at y = -2 under the floor and a black frame (mean 0 of 255)."""
    import dataclasses

    from test_panel import CAMERA, floor_bake, frames, panel_window

    level = dataclasses.replace(CAMERA, eye=[0.0, 1.0, 0.0], forward=[0.0, -0.5, -0.866])
    wnd, viewer = panel_window(floor_bake(tmp_path / "b"), camera=level)
    try:
        viewer.controls.speed = 1.0
        viewer.controls.key_press("q")
        frames(wnd, 60)  # 0.05 s each
        viewer.controls.key_release("q")
        assert viewer.controls.pose.eye[1] == pytest.approx(RADIUS, abs=1e-3)
        frames(wnd)
        picture = np.frombuffer(wnd.fbo.read(components=3), np.uint8)
        assert picture.mean() > 20
    finally:
        viewer.release()
        wnd.destroy()
