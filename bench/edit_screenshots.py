"""Screenshots of a material edit in `glint view`, for docs/VIEWER.md: the window's own frames
(viewer/window.py on moderngl-window's headless backend, the material panel drawn), before the
edit, with the object picked, right after the edit, and once the background re-bake
(bake/rebake.py, started as `glint view` starts it) has brought the light maps and cube maps up
to date.

    python3 -m glint.bench.edit_screenshots [--scene living-room] [--material "Sofa fabric"]
                                            [--kd 0.6,0.08,0.05] [--size 960x540] [--out docs/images]

Writes edit-1-before.png, edit-2-picked.png, edit-3-edited.png, edit-4-rebaked.png into --out and
prints the seconds the re-bake took. The scene is baked at draft quality in a temporary folder.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.scenes import resolve
from glint.services import background_rebake, bake_scene, parse_size, parse_vector
from glint.viewer.camera import ViewCamera
from glint.viewer.controls import WalkControls

STILL_FRAMES = 24  # still-camera frames before each shot


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="living-room")
    p.add_argument("--material", default="Sofa fabric")
    p.add_argument("--kd", default="0.6,0.08,0.05")
    p.add_argument("--size", default="960x540")
    p.add_argument("--out", type=Path, default=Path("docs/images"))
    args = p.parse_args()
    size = parse_size(args.size)
    kd = [float(c) for c in parse_vector(args.kd, "--kd")]
    scene_path = resolve(args.scene)
    from moderngl_window.context.headless import Window

    from glint.viewer.window import GL_VERSION, ViewerWindow

    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene(scene_path)
        bake_dir = Path(tmp) / "scene.bake"
        bake_scene(scene, resolve_settings(scene.bake_settings, quality="draft"), bake_dir, progress=False)
        bake = Bake(bake_dir)
        material = [m.name for m in bake.model.materials].index(args.material)
        camera = bake.model.cameras[0]
        home = ViewCamera.from_manifest(camera)
        wnd = Window(size=size, gl_version=GL_VERSION, backend="egl", aspect_ratio=None)
        with background_rebake(bake.model, bake_dir) as rebaker:
            viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=bake, controls=WalkControls([camera], [], home),
                                  lightmap_source=rebaker, on_edit=rebaker.edit)
            viewer.overlay.visible = False
            args.out.mkdir(parents=True, exist_ok=True)

            def shot(name: str, frames: int = STILL_FRAMES, quiet: bool = False) -> None:
                for _ in range(frames):
                    wnd.use()
                    wnd.render(0.0, 0.05)
                    wnd.swap_buffers()
                pixels = np.frombuffer(wnd.fbo.read(components=3), np.uint8).reshape(size[1], size[0], 3)[::-1]
                Image.fromarray(pixels).save(args.out / name)
                if not quiet:
                    print(f"wrote {args.out / name}", flush=True)

            viewer.panel.visible = False
            shot("edit-1-before.png")
            # pick the material's object under the pixel nearest the image centre that shows it
            ids = [(x, y) for y in range(0, size[1], 8) for x in range(0, size[0], 8)
                   if (viewer.renderer.pick(x, y) or (None, None))[1] == material]
            if not ids:
                raise SystemExit(f"'{args.material}' is not in view of the scene's first camera")
            x, y = min(ids, key=lambda q: (q[0] - size[0] / 2) ** 2 + (q[1] - size[1] / 2) ** 2)
            viewer.pick(x, y)
            viewer.panel.visible = True
            shot("edit-2-picked.png", 2)
            start = time.perf_counter()
            viewer.panel.set_kd(kd)
            shot("edit-3-edited.png")
            while True:  # until the re-bake's last pass and its probes are in the window
                shot("edit-4-rebaked.png", 1, quiet=True)
                if rebaker.done:
                    break
                time.sleep(0.5)
            seconds = time.perf_counter() - start
            shot("edit-4-rebaked.png")
            print(f"re-bake: {seconds:.1f} s from the edit to the last pass and its probes in the window")
            viewer.release()
        wnd.destroy()


if __name__ == "__main__":
    main()
