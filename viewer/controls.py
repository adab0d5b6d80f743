"""Walkthrough controls: key and mouse events in, one `ViewCamera` per frame out.

No OpenGL and no window here: the window (viewer/window.py) turns its backend's
key codes into names ("w", "shift", "f12", ...) and calls `key_press` / `key_release` /
`mouse_look` / `text`, then `update(dt)` once per frame. That keeps every rule
testable with plain numbers.

The keys are in KEY_HELP (also shown by `glint view --help`).

Orientation is kept as yaw and pitch with world +Y up: a walkthrough never
rolls, and a camera of the scene that does roll is levelled when selected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glint.core.manifest import Camera, CameraPath
from glint.viewer.camera import DEFAULT_YFOV, ViewCamera, camera_path_at, path_span

KEY_HELP = """\
    W A S D         walk forward / left / back / right (in the horizontal plane);
                    the arrow keys do the same
    E or Space      up          Q or C     down
    Shift (held)    4x faster   + / -      walking speed x1.5 / /1.5
    mouse drag      look around (yaw, pitch; pitch stops short of straight up/down)
    1-9, Tab        the scene's cameras (Shift+Tab: previous)
    P               play the camera path, looping (presentation mode); P again or
                    any walking key or mouse look stops it where it is
    F12, Ctrl+S     screenshot            F1    overlay on/off
    F, F11          fullscreen            Esc   quit
  editing materials (the material panel, Dear ImGui):
    click           pick the object under the cursor: the panel shows its material
                    (a click is a press and release without dragging; dragging looks)
    M               pick what is under the cursor       F2    panel on/off
    Ctrl+Z, Ctrl+Y  undo / redo an edit (Ctrl+Shift+Z: redo); the panel has Undo,
                    Redo, Revert (to the bake's materials) and Save (into the scene's
                    NAME.glint.toml); light maps and cube maps re-bake in the background
                    after an edit
"""

MOVE_KEYS = {  # name -> (forward, right, up) direction in the walker's frame
    "w": (1, 0, 0), "s": (-1, 0, 0), "d": (0, 1, 0), "a": (0, -1, 0),
    "e": (0, 0, 1), "space": (0, 0, 1), "q": (0, 0, -1), "c": (0, 0, -1),
    "up": (1, 0, 0), "down": (-1, 0, 0), "right": (0, 1, 0), "left": (0, -1, 0),  # arrow keys
}
ACTIONS = {"f12": "screenshot", "f1": "overlay", "f": "fullscreen", "f11": "fullscreen", "escape": "quit",
           "m": "pick", "f2": "panel"}

WALK_SPEED = 1.4  # m/s, a person walking
RUN_FACTOR = 4.0  # while Shift is held
SPEED_STEP = 1.5  # per + or - press
LOOK_SENSITIVITY = math.radians(0.15)  # per pixel of mouse movement
MAX_PITCH = math.radians(89.0)  # looking straight up/down would make "up" undefined
MAX_DT = 0.25  # s: a stall (a window drag, a slow first frame) must not teleport the walker


@dataclass
class Pose:
    eye: np.ndarray
    yaw: float  # radians, 0 looks along -Z, positive turns towards +X (to the right)
    pitch: float  # radians, positive looks up
    yfov: float = DEFAULT_YFOV
    znear: float = 0.01
    zfar: float = 1000.0

    @classmethod
    def of(cls, camera: ViewCamera) -> "Pose":
        f = camera.forward
        pitch = math.asin(float(np.clip(f[1], -1.0, 1.0)))
        yaw = math.atan2(float(f[0]), float(-f[2])) if math.hypot(f[0], f[2]) > 1e-9 else 0.0
        return cls(np.array(camera.eye, np.float64), yaw, float(np.clip(pitch, -MAX_PITCH, MAX_PITCH)),
                   camera.yfov, camera.znear, camera.zfar)

    def forward(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        return np.array([math.sin(self.yaw) * cp, math.sin(self.pitch), -math.cos(self.yaw) * cp])

    def camera(self, name: str = "") -> ViewCamera:
        return ViewCamera(self.eye.copy(), self.forward(), np.array([0.0, 1.0, 0.0]), self.yfov,
                          self.znear, self.zfar, name)


class WalkControls:
    """The walker's state; `cameras` and `paths` are the bake manifest's (`Bake.model`'s) lists."""

    def __init__(self, cameras: list[Camera], paths: list[CameraPath], home: ViewCamera, *,
                 start: str | None = None, speed: float = WALK_SPEED):
        self.cameras = [ViewCamera.from_manifest(c) for c in cameras]
        self.paths = paths
        self.camera_index = -1  # -1: the home view, not one of the scene's cameras
        self.pose = Pose.of(home)
        self.speed = speed
        self.held: set[str] = set()
        self.running = False  # Shift held
        self.playing = False
        self.path_time = 0.0
        # collide(eye, target) -> where a walking step ends (viewer/collision.py Collider.move, set
        # by the window from the bake's meshes); None: walking goes through surfaces
        self.collide = None
        if start is not None:
            names = [c.name for c in self.cameras]
            self.select_camera(names.index(start))  # the command line checked the name
        elif self.cameras:
            self.select_camera(0)

    # -- events ----------------------------------------------------------------------------------
    def key_press(self, name: str, *, ctrl: bool = False, shift: bool = False) -> str | None:
        """Handle a key going down. Returns an action for the window ("screenshot", "overlay",
        "fullscreen", "quit", "pick", "panel", "undo", "redo") or None when the controls dealt with it."""
        if name == "s" and ctrl:
            return "screenshot"  # Ctrl+S is not "walk back"
        if name == "z" and ctrl:
            return "redo" if shift else "undo"
        if name == "y" and ctrl:
            return "redo"
        if name in ACTIONS:
            return ACTIONS[name]
        if name == "shift":
            self.running = True
        elif name in MOVE_KEYS:
            self._take_over()
            self.held.add(name)
        elif name == "tab" and self.cameras:
            n = len(self.cameras)
            if self.camera_index < 0:  # from the home view: the first (or with Shift the last)
                self.select_camera(n - 1 if shift else 0)
            else:
                self.select_camera((self.camera_index + (-1 if shift else 1)) % n)
        elif len(name) == 1 and name in "123456789" and int(name) <= len(self.cameras):
            self.select_camera(int(name) - 1)
        elif name == "p":
            self.toggle_path()
        return None

    def key_release(self, name: str) -> None:
        if name == "shift":
            self.running = False
        self.held.discard(name)

    def text(self, char: str) -> None:
        """Typed characters, for keys that differ between keyboard layouts (+ is Shift+= on US ones)."""
        if char in "+=":
            self.speed *= SPEED_STEP
        elif char == "-":
            self.speed /= SPEED_STEP

    def mouse_look(self, dx: float, dy: float) -> None:
        """dx, dy in pixels, window coordinates (y grows downwards): moving right turns right,
        moving down looks down."""
        self._take_over()
        self.pose.yaw = math.remainder(self.pose.yaw + dx * LOOK_SENSITIVITY, math.tau)
        self.pose.pitch = float(np.clip(self.pose.pitch - dy * LOOK_SENSITIVITY, -MAX_PITCH, MAX_PITCH))

    def release_all(self) -> None:
        """Forget held keys (the window lost focus and will not see their release)."""
        self.held.clear()
        self.running = False

    # -- cameras and paths -----------------------------------------------------------------------
    def select_camera(self, index: int) -> None:
        self.playing = False
        self.camera_index = index
        self.pose = Pose.of(self.cameras[index])

    def toggle_path(self) -> None:
        if self.playing:
            self._take_over()
        elif self.paths:
            self.playing, self.path_time = True, path_span(self.paths[0])[0]

    def path_camera(self) -> ViewCamera:
        """The playing path's camera at `path_time`, looped over the path's time span."""
        path = self.paths[0]
        t0, t1 = path_span(path)
        t = t0 + math.fmod(self.path_time - t0, t1 - t0) if t1 > t0 else t0
        return camera_path_at(path, t, yfov=self.pose.yfov, znear=self.pose.znear, zfar=self.pose.zfar)

    def _take_over(self) -> None:
        """Stop a playing path and walk on from where it was."""
        if self.playing:
            self.playing = False
            pose = Pose.of(self.path_camera())
            self.pose.eye, self.pose.yaw, self.pose.pitch = pose.eye, pose.yaw, pose.pitch

    # -- per frame -------------------------------------------------------------------------------
    @property
    def current_speed(self) -> float:
        return self.speed * (RUN_FACTOR if self.running else 1.0)

    @property
    def status(self) -> str:
        """One line for the overlay."""
        if self.playing:
            return f"path '{self.paths[0].get('name', '')}' t={self.path_time:.1f} s (P stops)"
        where = self.cameras[self.camera_index].name if self.camera_index >= 0 else "home"
        x, y, z = self.pose.eye
        return f"from {where}  eye {x:.2f} {y:.2f} {z:.2f}  speed {self.current_speed:.2f} m/s"

    def update(self, dt: float) -> ViewCamera:
        """Advance by dt seconds and return the camera for this frame."""
        dt = min(max(dt, 0.0), MAX_DT)
        if self.playing:
            self.path_time += dt
            return self.path_camera()
        move = np.zeros(3)
        for name in self.held:
            move += MOVE_KEYS[name]
        if move.any():
            # Walking stays level whatever the pitch: forward is the view direction projected
            # onto the ground plane, right is perpendicular to it.
            yaw = self.pose.yaw
            ahead = np.array([math.sin(yaw), 0.0, -math.cos(yaw)])
            right = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
            direction = move[0] * ahead + move[1] * right + move[2] * np.array([0.0, 1.0, 0.0])
            norm = np.linalg.norm(direction)
            if norm > 0:  # opposite keys cancel
                target = self.pose.eye + direction / norm * self.current_speed * dt
                self.pose.eye = target if self.collide is None else np.asarray(self.collide(self.pose.eye, target))
        return self.pose.camera()
