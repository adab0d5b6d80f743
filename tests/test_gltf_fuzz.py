"""Fuzzing the glTF/GLB reader (bake/gltf_loader.py `load_scene`): every mutated file ends in a Scene
or exactly one GlintError line that names the file; never another exception, a hang or a memory blow-up.

Seeds: three small valid scenes written with scenes/gltf_writer.py (`_seeds`): a .glb with its PNG
texture in a bufferView, a .gltf + .bin with the PNG as a separate file (`uri`), and a .gltf whose
texture is a `data:` URI; each has a textured floor (TEXCOORD_0, an emissive texture too), a lamp, a
box, a punctual light, a camera and a child node. Each case applies one to three mutations
(`mutate`): structure-aware ones on the JSON (a value replaced by another type, an index out of range,
a count or length of 2**31 and more, a key deleted, two table entries swapped, a sparse accessor or a
Draco/meshopt extension added with random fields, a PNG's declared size changed) and byte-level ones
(bit flips, truncation, 32-bit words overwritten, bytes inserted or deleted) on the .glb, the .gltf's
text or its .bin.

How a case runs: in a worker process (`_Worker`, this file run as a script) with its address space
capped (resource.setrlimit RLIMIT_AS = the worker's size after its imports + MEMORY_BUDGET), so
an allocation past the budget fails at once (MemoryError) instead of being granted lazily; each
case has CASE_SECONDS (SIGALRM in the worker, and the parent kills a worker that does not answer in
twice that). A worker that dies is restarted and the case recorded.

What counts as a failure (the assertion lists each with its case id and mutations, and the seed):
- an exception other than GlintError (MemoryError included), a hang, a dead worker;
- a GlintError of more than one line, or one that does not name the file;
- the generic fallback line of `_guarded` ("malformed glTF (KeyError: ...)"), which names an
  exception rather than what is wrong;
- PIL's own text (DecompressionBomb...) on stderr or as a Python warning.

Counts: GLINT_FUZZ_CASES (default 2000: about 10 s here on 2 cores, CI), GLINT_FUZZ_SEED (default 22).
The long run: `GLINT_FUZZ_CASES=20000 pytest tests/test_gltf_fuzz.py` (docs/SCENES.md, section 5), or
`python tests/test_gltf_fuzz.py FOLDER` with the same variables, which lists every failure and counts
them by kind. A failure reproduces with the same seed (GLINT_FUZZ_FIRST=<case id> GLINT_FUZZ_CASES=1).

Bugs it found in the loader (each fixed; the fix removed again, the test failed as said):
- JSON values of another type than glTF's (a string index, a number for an object): the generic
  "malformed glTF (TypeError: ...)" line from 30 places (180 of 3000 cases); now bake/gltf_schema.py.
  Without its call: 104 of the 2000 CI cases fail.
- a meshopt bufferView's count of 2**31 and more: std::bad_alloc (MemoryError) in meshopt's decoder
  (6 of 3000); an accessor without bufferView and a huge count: numpy's MemoryError (found once the
  "unbacked" mutation was added). Now MAX_UNBACKED_BYTES. Without it: 5 and 65 of 2000 fail.
- a PNG declaring more than 89 Mpx: PIL's DecompressionBombWarning on stderr, or its error quoted in
  glint's warning (about 110 of 3000); now bake/texture_image.py (tests/test_texture_limits.py).
- an image Pillow cannot identify: "<_io.BytesIO object at 0x...>" in the warning (50 of 3000).
- NORMAL not VEC3, TEXCOORD_n not VEC2: a ValueError from matmul (2 of 20000, seed 22).
The metric: the number of failing cases, 0.
"""
from __future__ import annotations

import base64
import copy
import json
import os
import random
import resource
import select
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np

FUZZ_CASES = int(os.environ.get("GLINT_FUZZ_CASES", "2000"))
FUZZ_SEED = int(os.environ.get("GLINT_FUZZ_SEED", "22"))
FUZZ_FIRST = int(os.environ.get("GLINT_FUZZ_FIRST", "0"))
CASE_SECONDS = 20.0  # a tiny file loads in ~20 ms; a 16384^2 PNG (the largest decoded) in ~5 s
MEMORY_BUDGET = 3 << 30  # bytes of address space beyond the worker's own after its imports
_GLB_MAGIC, _JSON, _BIN = 0x46546C67, 0x4E4F534A, 0x004E4942

# ---------------------------------------------------------------------------------------- seeds


def _texture(size: int = 8) -> np.ndarray:
    y, x = np.mgrid[:size, :size]
    return np.stack([(x * 255 // size), (y * 255 // size), ((x + y) % 2) * 255], axis=-1).astype(np.uint8)


def _writer():
    from glint.scenes.gltf_writer import GltfWriter, quad

    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(0.8, 0.8, 0.8, 1.0), base_color_texture=_texture(),
                           emissive_texture=_texture(4), texture_transform={"scale": [2.0, 2.0]})
    lamp = w.add_material("Lamp", emissive=(1, 1, 1), emissive_strength=5.0)
    p, i = quad((0, 0, 0), (1, 0, 0), (0, 0, -1))
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, floor, normals=np.tile([0.0, 1.0, 0.0], (4, 1)),
                                        uvs=(p[:, [0, 2]] + 1) / 2))
    p, i = quad((0, 1.9, 0), (0.2, 0, 0), (0, 0, 0.2))
    box = w.add_node("Box", mesh=w.add_mesh("Box", *quad((0, 0.5, 0), (0.3, 0, 0), (0, 0.3, 0)), floor))
    w.add_node("Lamp", mesh=w.add_mesh("Lamp", p, i, lamp), children=[box], rotation=(0, 0, 0, 1))
    w.add_node("Bulb", light=w.add_light("Bulb", "spot", intensity=20.0, outer_cone_angle=0.6),
               translation=(0, 1.5, 0))
    w.add_node("Camera", camera=w.add_camera("Camera", 1.0), translation=(0, 1, 1.5))
    return w


def _seeds(folder: Path) -> list[dict[str, bytes]]:
    """The seed scenes as {file name: bytes}; the first file is the one loaded."""
    folder.mkdir(parents=True, exist_ok=True)
    _writer().write(folder / "s.glb")
    _writer().write(folder / "s.gltf")
    glb = {"scene.glb": (folder / "s.glb").read_bytes()}
    doc = json.loads((folder / "s.gltf").read_text())
    binary = (folder / "s.bin").read_bytes()
    doc["buffers"][0]["uri"] = "scene.bin"
    with_uri, with_data = copy.deepcopy(doc), copy.deepcopy(doc)
    files = {}
    for k, image in enumerate(doc["images"]):  # images out of the buffer: a file, and a data: URI
        view = doc["bufferViews"][image["bufferView"]]
        png = binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
        files[f"tex{k}.png"] = png
        with_uri["images"][k] = {"uri": f"tex{k}.png"}
        with_data["images"][k] = {"uri": "data:image/png;base64," + base64.b64encode(png).decode()}
    return [glb,
            {"scene.gltf": json.dumps(with_uri, indent=1).encode(), "scene.bin": binary, **files},
            {"scene.gltf": json.dumps(with_data).encode(), "scene.bin": binary}]


# ------------------------------------------------------------------------------------ mutations

TYPES = [None, True, False, -1, 0, 1, 2, 3, 7, 2**31, 2**32 + 5, 2**53, -2**31, 1e308, 0.5, float("nan"),
         float("inf"), "x", "", "0", [], [0], [1, 2, 3], {}, {"a": 1}]
HUGE = [2**31, 2**31 - 1, 2**32, 2**32 - 1, 2**40, 2**53, 2**63, 2**64, 10**30, -1, -2**31, 1 << 28]
COUNTS = ("count", "byteLength", "byteOffset", "byteStride")
INDICES = ("bufferView", "buffer", "mesh", "material", "camera", "source", "sampler", "index", "indices",
           "POSITION", "NORMAL", "TEXCOORD_0", "TEXCOORD_1", "COLOR_0", "TANGENT", "scene", "light",
           "texCoord", "children", "nodes", "mode", "componentType")
DIMENSIONS = [0, 1, 12000, 16384, 16385, 20000, 65535, 100000, 2**31 - 1, 2**32 - 1]


def _paths(tree, path=()):
    """Every (path, value) of a JSON tree, containers included."""
    yield path, tree
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _paths(v, path + (k,))
    elif isinstance(tree, list):
        for k, v in enumerate(tree):
            yield from _paths(v, path + (k,))


def _set(tree, path, value):
    for k in path[:-1]:
        tree = tree[k]
    tree[path[-1]] = value


def _json_mutation(rng: random.Random, doc: dict) -> str:
    paths = [p for p, _ in _paths(doc) if p]
    op = rng.choice(["type", "type", "index", "index", "count", "delete", "swap", "sparse", "draco",
                     "meshopt", "valid", "unbacked"])
    if op == "unbacked":  # an accessor of zeros: its size is the count alone
        accessors = doc.get("accessors")
        if not isinstance(accessors, list) or not accessors or not isinstance(accessors[0], dict):
            return "unbacked: none"
        k, count = rng.randrange(len(accessors)), rng.choice(HUGE + [4, 100])
        if isinstance(accessors[k], dict):
            accessors[k].pop("bufferView", None)
            accessors[k]["count"] = count
        return f"accessors/{k}: no bufferView, count {count!r}"
    if op == "type":
        path = rng.choice(paths)
        value = rng.choice(TYPES)
        _set(doc, path, value)
        return f"{'/'.join(map(str, path))} = {value!r}"
    if op in ("index", "count", "valid"):
        keys = COUNTS if op == "count" else INDICES
        hits = [p for p, v in _paths(doc) if p and (p[-1] in keys or (isinstance(p[-1], int) and len(p) > 1
                                                                      and p[-2] in keys))]
        hits = hits or paths
        path = rng.choice(hits)
        if op == "count":
            value = rng.choice(HUGE)
        elif op == "valid":  # a valid-looking value of the wrong meaning
            value = rng.choice([5120, 5121, 5122, 5123, 5125, 5126, 0, 1, 2, 3, 4, 5, 6, "VEC2", "SCALAR", "MAT4"])
        else:
            table = {"bufferView": "bufferViews", "buffer": "buffers", "mesh": "meshes", "material": "materials",
                     "camera": "cameras", "source": "images", "sampler": "samplers", "index": "textures",
                     "nodes": "nodes", "children": "nodes"}.get(path[-1] if isinstance(path[-1], str) else path[-2],
                                                                "accessors")
            size = len(doc.get(table, [])) if isinstance(doc.get(table), list) else 0
            value = rng.choice([size, size + 1, size + 1000, -1, 2**31, 2**63, 1.0, "0", True, None])
        _set(doc, path, value)
        return f"{'/'.join(map(str, path))} = {value!r}"
    if op == "delete":
        dicts = [(p, v) for p, v in _paths(doc) if isinstance(v, dict) and v]
        path, d = rng.choice(dicts)
        key = rng.choice(list(d))
        del d[key]
        return f"del {'/'.join(map(str, path + (key,)))}"
    if op == "swap":
        lists = [(p, v) for p, v in _paths(doc) if isinstance(v, list) and len(v) > 1]
        if not lists:
            return "swap: none"
        path, items = rng.choice(lists)
        a, b = rng.sample(range(len(items)), 2)
        items[a], items[b] = items[b], items[a]
        return f"swap {'/'.join(map(str, path))}[{a}, {b}]"
    if op == "sparse":
        accessors = doc.get("accessors")
        if not isinstance(accessors, list) or not accessors or not isinstance(accessors[0], dict):
            return "sparse: none"
        k = rng.randrange(len(accessors))
        sparse = {"count": rng.choice([1, 2, 3, 2**31, -1, "1"]),
                  "indices": {"bufferView": rng.choice([0, 1, 2, 99]), "byteOffset": rng.choice([0, 4, 2**40]),
                              "componentType": rng.choice([5121, 5123, 5125, 5126, 1])},
                  "values": {"bufferView": rng.choice([0, 1, 2, 99]), "byteOffset": rng.choice([0, 8, -4])}}
        if isinstance(accessors[k], dict):
            accessors[k]["sparse"] = sparse
        return f"accessors/{k}/sparse = {sparse}"
    if op == "draco":
        meshes = doc.get("meshes")
        if not isinstance(meshes, list) or not meshes or not isinstance(meshes[0], dict):
            return "draco: none"
        prim = (meshes[0].get("primitives") or [{}])[0]
        ext = {"bufferView": rng.choice([0, 1, 3, 99, -1]),
               "attributes": {"POSITION": rng.choice([0, 1, 7, "0"]), "NORMAL": rng.choice([1, 2])}}
        if isinstance(prim, dict):
            prim["extensions"] = {"KHR_draco_mesh_compression": ext}
        return f"meshes/0/primitives/0 draco {ext}"
    views = doc.get("bufferViews")
    if not isinstance(views, list) or not views:
        return "meshopt: none"
    k = rng.randrange(len(views))
    ext = {"buffer": rng.choice([0, 1, -1]), "byteOffset": rng.choice([0, 4, 2**33]),
           "byteLength": rng.choice([0, 16, 48, 2**31]), "byteStride": rng.choice([0, 4, 12, 255, 2**31]),
           "count": rng.choice([0, 4, 2**31, 2**40]), "mode": rng.choice(["ATTRIBUTES", "TRIANGLES", "INDICES", "X"]),
           "filter": rng.choice(["NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR", "Y"])}
    if isinstance(views[k], dict):
        views[k]["extensions"] = {"EXT_meshopt_compression": ext}
    return f"bufferViews/{k} meshopt {ext}"


def _png_resize(rng: random.Random, png: bytes) -> tuple[bytes, str]:
    """The PNG with another declared size in its IHDR (CRC fixed, mostly), its pixels as they were."""
    if png[:8] != b"\x89PNG\r\n\x1a\n" or png[12:16] != b"IHDR":
        return png, "png: none"
    w, h = rng.choice(DIMENSIONS), rng.choice(DIMENSIONS + [8])
    ihdr = b"IHDR" + struct.pack(">II", w, h) + png[24:29]
    crc = zlib.crc32(ihdr) if rng.random() < 0.9 else 0
    return png[:12] + ihdr + struct.pack(">I", crc) + png[33:], f"png declares {w}x{h}"


def _byte_mutation(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    b = bytearray(data)
    if not b:
        return data, "bytes: empty"
    op = rng.choice(["flip", "truncate", "word", "insert", "delete"])
    if op == "flip":
        at = [rng.randrange(len(b)) for _ in range(rng.randint(1, 8))]
        for i in at:
            b[i] ^= 1 << rng.randrange(8)
        return bytes(b), f"flip bits at {at}"
    if op == "truncate":
        n = rng.randrange(len(b))
        return bytes(b[:n]), f"truncate to {n}"
    if op == "word":
        i = rng.randrange(0, max(len(b) - 3, 1), 4) if len(b) >= 4 else 0
        value = rng.choice([0, 1, 0xFFFFFFFF, 0x7FFFFFFF, 0x80000000, rng.getrandbits(32)])
        b[i:i + 4] = struct.pack("<I", value)
        return bytes(b), f"word at {i} = {value:#x}"
    i, n = rng.randrange(len(b)), rng.randint(1, 64)
    if op == "insert":
        return bytes(b[:i] + bytes(rng.getrandbits(8) for _ in range(n)) + b[i:]), f"insert {n} at {i}"
    return bytes(b[:i] + b[i + n:]), f"delete {n} at {i}"


def _split_glb(data: bytes) -> tuple[dict, bytes]:
    (n,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20:20 + n])
    m = struct.unpack_from("<I", data, 20 + n)[0]
    return doc, data[28 + n:28 + n + m]


def _glb(doc: dict, binary: bytes) -> bytes:
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), _JSON) + text + struct.pack("<II", len(binary), _BIN) + binary
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def mutate(seeds: list[dict[str, bytes]], case: int, seed: int) -> tuple[dict[str, bytes], list[str]]:
    """Case `case` of run `seed`: ({file name: bytes}, what was done), the same for the same numbers."""
    rng = random.Random(f"{seed}:{case}")
    files = dict(seeds[case % len(seeds)])
    main = next(iter(files))
    glb = main.endswith(".glb")
    if glb:
        doc, binary = _split_glb(files[main])
    else:
        doc, binary = json.loads(files[main]), files["scene.bin"]
    done = []
    structural = []  # JSON and PNG mutations first, byte mutations on the container after
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        structural.append(rng.random() < 0.7 if rng.random() < 0.85 else "png")
    for kind in structural:
        if kind == "png":
            pngs = [name for name in files if name.endswith(".png")]
            if pngs:
                name = rng.choice(pngs)
                files[name], what = _png_resize(rng, files[name])
                done.append(f"{name}: {what}")
            else:
                start = binary.find(b"\x89PNG")
                if start >= 0:
                    png, what = _png_resize(rng, binary[start:])
                    binary = binary[:start] + png
                    done.append(f"bin: {what}")
        elif kind:
            done.append(_json_mutation(rng, doc))
    if glb:
        files[main] = _glb(doc, binary)
    else:
        files[main], files["scene.bin"] = json.dumps(doc, allow_nan=True).encode(), binary
    for kind in structural:
        if kind is False:  # a byte-level mutation of one of the files
            name = rng.choice(list(files))
            files[name], what = _byte_mutation(rng, files[name])
            done.append(f"{name}: {what}")
    return files, done


# --------------------------------------------------------------------------------------- worker


def _worker_main(folder: str) -> None:
    """Read case folders from stdin, one a line; answer one JSON line each on stdout."""
    import contextlib
    import io
    import traceback
    import warnings

    from glint.bake.gltf_loader import load_scene
    from glint.core.errors import GlintError

    out = sys.stdout
    soft = _address_space() + MEMORY_BUDGET
    resource.setrlimit(resource.RLIMIT_AS, (soft, soft))

    def alarm(*_):
        raise TimeoutError(f"more than {CASE_SECONDS} s")

    signal.signal(signal.SIGALRM, alarm)
    out.write("ready\n")
    out.flush()
    for line in sys.stdin:
        case_dir = Path(line.strip())
        main = next(p for p in sorted(case_dir.iterdir()) if p.suffix in (".glb", ".gltf"))
        err, t0 = io.StringIO(), time.perf_counter()
        answer = {}
        with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stderr(err), \
                contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("always")
            signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
            try:
                load_scene(main)
                answer["outcome"] = "scene"
            except GlintError as e:
                answer.update(outcome="error", message=str(e))
                if e.__cause__ is not None:  # where a fallback's exception came from, for the report
                    frame = traceback.extract_tb(e.__cause__.__traceback__)[-1]
                    answer["cause"] = f"{Path(frame.filename).name}:{frame.lineno} {frame.name}"
            except BaseException as e:  # noqa: BLE001 (what the fuzzer is looking for)
                frame = traceback.extract_tb(e.__traceback__)[-1]
                answer.update(outcome=type(e).__name__, message=f"{str(e)[:300]} "
                              f"({Path(frame.filename).name}:{frame.lineno} {frame.name})")
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
        answer["seconds"] = time.perf_counter() - t0
        answer["stderr"] = err.getvalue()[-2000:]
        answer["warnings"] = [f"{w.category.__name__}: {w.message}"[:300] for w in caught]
        out.write(json.dumps(answer) + "\n")
        out.flush()


def _address_space() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


class _Worker:
    def __init__(self, folder: Path):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker", str(folder)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True)
        assert self._read(120) == "ready", "the fuzz worker did not start"

    def _read(self, seconds: float) -> str | None:
        ready, _, _ = select.select([self.proc.stdout], [], [], seconds)
        return self.proc.stdout.readline().strip() if ready else None

    def run(self, case_dir: Path) -> dict:
        self.proc.stdin.write(f"{case_dir}\n")
        self.proc.stdin.flush()
        line = self._read(2 * CASE_SECONDS + 10)
        if not line:
            self.close()
            return {"outcome": "hang or dead worker", "message": f"no answer in {2 * CASE_SECONDS + 10:.0f} s "
                    f"(exit status {self.proc.returncode})"}
        return json.loads(line)

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


def judge(answer: dict, main: str) -> str | None:
    """Why a case's outcome is a failure, or None."""
    outcome, message = answer["outcome"], answer.get("message", "")
    pil = [w for w in answer.get("warnings", []) if "DecompressionBomb" in w]
    if outcome not in ("scene", "error"):
        return f"{outcome}: {message}"
    if outcome == "error":
        if "\n" in message:
            return f"GlintError of {message.count(chr(10)) + 1} lines: {message[:300]!r}"
        if main not in message:
            return f"GlintError not naming {main}: {message[:300]!r}"
        if "malformed glTF (" in message:
            return f"the generic fallback: {message[:300]!r} at {answer.get('cause')}"
    if pil or "DecompressionBomb" in answer.get("stderr", "") or "<_io." in answer.get("stderr", ""):
        return f"PIL's own text: {(pil or [answer.get('stderr', '')])[0][:300]!r}"
    return None


def run_fuzz(folder: Path, cases: range, seed: int) -> tuple[list[str], dict]:
    """Run `cases`; (failures, figures: outcome counts and time)."""
    seeds = _seeds(folder / "seeds")
    worker, failures, counts = _Worker(folder), [], {}
    t0, slowest = time.perf_counter(), (0.0, -1)
    try:
        for case in cases:
            files, done = mutate(seeds, case, seed)
            case_dir = folder / f"case{case % 2}"
            if case_dir.exists():
                for p in case_dir.iterdir():
                    p.unlink()
            case_dir.mkdir(exist_ok=True)
            for name, data in files.items():
                (case_dir / name).write_bytes(data)
            answer = worker.run(case_dir)
            if answer["outcome"] == "hang or dead worker":
                worker = _Worker(folder)
            main = next(iter(files))
            why = judge(answer, main)
            key = "failed" if why else answer["outcome"]
            counts[key] = counts.get(key, 0) + 1
            slowest = max(slowest, (answer.get("seconds", 0.0), case))
            if why:
                failures.append(f"seed {seed} case {case} ({'; '.join(done)}): {why}")
    finally:
        worker.close()
    counts["seconds"] = round(time.perf_counter() - t0, 1)
    counts["slowest case"] = f"{slowest[1]} ({slowest[0]:.2f} s)"
    return failures, counts


def test_fuzz_gltf_reader(tmp_path):
    """GLINT_FUZZ_CASES mutated files (default 2000, seed GLINT_FUZZ_SEED): each a Scene or one GlintError
    line naming the file (`judge`); the metric is the number of failing cases, which must be 0."""
    failures, counts = run_fuzz(tmp_path, range(FUZZ_FIRST, FUZZ_FIRST + FUZZ_CASES), FUZZ_SEED)
    print(f"fuzz: {counts}")
    assert not failures, f"{len(failures)} of {FUZZ_CASES} cases failed ({counts}):\n" + "\n".join(failures[:40])
    # The mutations reach past the container: some cases still load, many fail at different checks.
    assert counts.get("scene", 0) > FUZZ_CASES // 20 and counts.get("error", 0) > FUZZ_CASES // 4, counts


def test_huge_count_without_data_refused(tmp_path):
    """An accessor without a bufferView (zeros) and count 2**31 (24 GiB as VEC3 float32): one GlintError
    naming the accessor and the size, from the worker whose address space is capped at MEMORY_BUDGET
    beyond its own (without the check: MemoryError from numpy)."""
    files = dict(_seeds(tmp_path / "seeds")[0])
    doc, binary = _split_glb(files["scene.glb"])
    doc["accessors"][0].pop("bufferView")
    doc["accessors"][0]["count"] = 2**31
    (tmp_path / "case").mkdir()
    (tmp_path / "case" / "scene.glb").write_bytes(_glb(doc, binary))
    worker = _Worker(tmp_path)
    try:
        answer = worker.run(tmp_path / "case")
    finally:
        worker.close()
    assert answer["outcome"] == "error", answer
    assert answer["message"].startswith("scene.glb: malformed glTF: accessor 0 (") and "24,576 MiB" in answer["message"]


def test_seeds_load(tmp_path):
    """The unmutated seeds load, with the textures read (the fuzz cases start from valid files)."""
    from glint.bake.gltf_loader import load_scene

    for k, files in enumerate(_seeds(tmp_path / "seeds")):
        folder = tmp_path / f"seed{k}"
        folder.mkdir()
        for name, data in files.items():
            (folder / name).write_bytes(data)
        scene = load_scene(folder / next(iter(files)))
        floor = next(m for m in scene.materials if m.name == "Floor")
        assert floor.kd_texture.shape == (8, 8, 3) and floor.emission_texture.shape == (4, 4, 3)
        assert [o.name for o in scene.objects] == ["Floor", "Box", "Lamp"] and len(scene.cameras) == 1


if __name__ == "__main__" and sys.argv[1:2] == ["--worker"]:
    _worker_main(sys.argv[2])
elif __name__ == "__main__":  # python tests/test_gltf_fuzz.py FOLDER: every failure, not the first 40
    import collections

    fails, figures = run_fuzz(Path(sys.argv[1]), range(FUZZ_FIRST, FUZZ_FIRST + FUZZ_CASES), FUZZ_SEED)
    print("\n".join(fails))
    print(figures)
    print(collections.Counter(f.split("): ", 1)[1][:70] for f in fails).most_common(60))
