"""Still-camera refinement (section 4.4.2): while nothing changes, every frame adds quasi-random
importance samples and the image shown is the running mean of the frames, which converges to
the integral of the cube maps' light (the walkthrough's regular patterns only approximate it).

    progressive = Progressive(ctx, defines, samples_per_frame=8)
    restarted = progressive.begin(key)        # key: Progressive.view_key(camera, size, ...)
    first, count = progressive.samples()      # this frame's part of the quasi-random sequence
    ...shade with samples first .. first + count - 1...
    shown = progressive.add(frame_radiance)   # fp32 sum += frame; shown = sum / frames

Frame k takes samples k K .. k K + K - 1 of the sequence (K = samples_per_frame), so
the frame index alone drives it: N frames give the same image every time, and N frames
of K samples equal N K samples in one frame (up to float rounding). Any change of the
key -- camera, image size, supersampling, exposure -- restarts at frame 0, and so does
`invalidate()` (the renderer calls it for every walkthrough frame). After `max_frames`
frames the image is final (`converged`) and the renderer stops adding to it.

`blend_frames` > 0 (the window) fades from the walkthrough image the camera stopped on
to the mean over that many frames, so stopping does not flash the noise of the first
few samples; 0 (captures) shows the plain running mean from the first frame on.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.viewer.passes.accumulate import AccumulatePass

DEFAULT_SAMPLES_PER_FRAME = 8
DEFAULT_MAX_FRAMES = 512       # 4096 samples per lobe and pixel at the default K
MAX_SEQUENCE = 2 ** 31 - 1     # sample indices are GLSL ints


class Progressive:
    def __init__(self, ctx: moderngl.Context, defines: dict | None = None, *,
                 samples_per_frame: int = DEFAULT_SAMPLES_PER_FRAME, max_frames: int = DEFAULT_MAX_FRAMES,
                 blend_frames: int = 0):
        if not (isinstance(samples_per_frame, (int, np.integer)) and 1 <= samples_per_frame <= 4096):
            raise ValueError(f"samples per frame must be a whole number from 1 to 4096 (got {samples_per_frame!r})")
        if not (isinstance(max_frames, (int, np.integer)) and max_frames >= 1):
            raise ValueError(f"max_frames must be a whole number of at least 1 (got {max_frames!r})")
        self.samples_per_frame = int(samples_per_frame)
        self.max_frames = int(min(max_frames, MAX_SEQUENCE // self.samples_per_frame))
        self.blend_frames = max(int(blend_frames), 0)
        self.accumulate = AccumulatePass(ctx, defines)
        self.key = None
        self.frames = 0  # frames in the current sum

    @staticmethod
    def view_key(camera, size, supersample: int, exposure: float) -> tuple:
        """Everything whose change makes the accumulated image stale."""
        vec = lambda v: tuple(float(x) for x in np.asarray(v, np.float64).ravel())  # noqa: E731
        return (vec(camera.eye), vec(camera.forward), vec(camera.up), float(camera.yfov), float(camera.znear),
                float(camera.zfar), tuple(int(s) for s in size), int(supersample), float(exposure))

    def begin(self, key) -> bool:
        """Start a frame for `key`; True when that restarts the sum (a new or changed view)."""
        if key != self.key:
            self.key = key
            self.frames = 0
            return True
        return False

    def invalidate(self) -> None:
        self.key = None
        self.frames = 0

    @property
    def converged(self) -> bool:
        return self.frames >= self.max_frames

    def samples(self) -> tuple[int, int]:
        """(index of the first sample, sample count) of the frame being made."""
        return self.frames * self.samples_per_frame, self.samples_per_frame

    def keep_base(self, image: moderngl.Texture) -> None:
        """The walkthrough image to fade from (blend_frames > 0)."""
        self.accumulate.keep_base(image)

    def blend(self, has_base: bool) -> float:
        """Weight of the mean after the frame being added (1: the plain mean)."""
        if not has_base or self.blend_frames == 0:
            return 1.0
        return min(1.0, (self.frames + 1) / self.blend_frames)

    def add(self, radiance: moderngl.Texture, blend: float = 1.0) -> moderngl.Texture:
        """Add this frame's estimate; returns the image to show."""
        shown = self.accumulate.run(radiance, self.frames, blend)
        self.frames += 1
        return shown

    @property
    def shown(self) -> moderngl.Texture | None:
        return self.accumulate.shown

    def describe(self) -> dict:
        return {"frames": self.frames, "samples_per_frame": self.samples_per_frame,
                "samples_per_pixel": self.frames * self.samples_per_frame, "max_frames": self.max_frames,
                "converged": self.converged}

    def release(self) -> None:
        self.accumulate.release()

