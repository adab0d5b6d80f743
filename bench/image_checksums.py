"""SHA-256 of every image the built-in scenes produce, for proving a refactor changes no pixel.

For each built-in scene: a draft bake (checksums of its light maps and cube maps), then for every
camera a walkthrough PNG and EXR and a converged (still camera) EXR, and the living room's tour.
Runs the installed `glint` command, so the same script checks any two commits:

    python3 -m glint.bench.image_checksums OUT_DIR > before.txt   # at the old commit
    python3 -m glint.bench.image_checksums OUT_DIR > after.txt    # at the new one; diff the two
"""
import hashlib
import subprocess
import sys
from pathlib import Path

SCENES = {"cornell-box": ["sensor"], "living-room": ["entrance", "sofa"],
          "material-classes": ["front"], "planar-classes": ["front"]}


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def glint(*args) -> None:
    subprocess.run(["glint", *map(str, args)], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main() -> int:
    if len(sys.argv) != 2 or sys.argv[1].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    for scene, cams in SCENES.items():
        bake = out / f"{scene}.bake"
        glint("bake", scene, "-q", "draft", "-o", bake)
        for f in sorted(bake.rglob("*")):
            if f.is_file() and f.suffix in (".exr", ".png", ".bin", ".npy", ".npz"):
                print(f"{scene} bake/{f.relative_to(bake)} {sha(f)}")
        for cam in cams:
            common = [scene, "--bake-dir", bake, "-q", "draft", "--camera", cam, "--size", "160x96"]
            for name, extra in [("walk.png", []), ("walk.exr", []), ("walk-ss1.exr", ["--supersample", "1"]),
                                ("converge4.exr", ["--converge", "4"]),
                                ("splitsum.exr", ["--walkthrough-method", "split-sum"])]:
                f = out / f"{scene}-{cam}-{name}"
                glint("capture", *common, *extra, "-o", f)
                print(f"{scene} {cam} {name} {sha(f)}")
    glint("capture", "living-room", "--bake-dir", out / "living-room.bake", "-q", "draft", "--path", "tour",
          "--frames", "3", "--size", "160x96", "-o", out / "tour.png")
    for f in sorted(out.glob("tour_*.png")):
        print(f"living-room tour {f.name} {sha(f)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
