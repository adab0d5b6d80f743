#!/bin/bash
# Issue 27's GPU measurements in one run of the device machine (docs/VIEWER.md, "On a GPU"); results in
# docs/bench/h200/. About 510 s there (190 s of it the two bakes), plus the machine's start; eight files
# come back (the device's limit): log.txt, ft1/ft2 .md and .json, vis.md, scissor.md (with
# the mirror buffers at half resolution), drawcount.md.
#
# Preparation, on this machine, in the repository's root:
#   echo /.devdata/ >> .git/info/exclude; mkdir -p .devdata/b
#   bash ../shared/device/prepare.sh                      # the wheels (glint's from the working tree)
#   python3 -c "from pathlib import Path; from glint.bench.measure_draw_count import bake_for
#   [bake_for(n, Path('.devdata/b')) for n in ('living-room', 'cornell-box', 'planar-classes', 'many-10')]"
#   cp ../shared/scenes/wooden-staircase/wooden-staircase.glb .devdata/; git rev-parse HEAD > .devdata/commit
# then the device tool's run: command "bash .device/run.sh bash bench/gpu_frame.sh", carry [".device", ".devdata"]
# (about 62 MiB of the 64 that travel). The staircase's and many-10000's draft bakes (126 MB and 46 MB)
# do not fit: they are made there. The other draft bakes are made here; a bake moves between machines
# (no path enters its hash).
#
# .devdata/b holds the draft bakes; each step has its own time limit and the next runs whatever happens to it.
set -u; export PYTHONSAFEPATH=1  # the repo root holds a glint/ folder: import the installed package
B=${B:-.devdata/b}; S=${S:-.devdata/wooden-staircase.glb}; O=${OUT:-/tmp/out}; mkdir -p $O
HD=${HD:-1920x1080}; UHD=${UHD:-3840x2160}
step() { echo "== $(date +%T) [$SECONDS s] $*"; }
echo "commit $(cat .devdata/commit 2>/dev/null)"; nproc; lscpu 2>/dev/null | grep -E "^(Model name|Thread|Core|Socket|CPU\(s\))"
python3 -c "import os; from glint.parallel.cpus import usable_cpus, cgroup_quota
print('cpu_count', os.cpu_count(), 'affinity', len(os.sched_getaffinity(0)), 'quota', cgroup_quota(), 'workers', usable_cpus())"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,temperature.gpu --format=csv 2>/dev/null

step "1 frame times, built-in scenes, both ways"
timeout 170 python3 -m glint.bench.measure_frame_times --bake-root $B --quality draft --gbuffer raster,visibility \
  --supersample 1 --sizes $HD,$UHD --scenes living-room,cornell-box,planar-classes --out /tmp/ft1
cp /tmp/ft1/frame_times.md $O/ft1.md; cp /tmp/ft1/frame_times.json $O/ft1.json

step "2 visibility against raster, built-in scenes"
timeout 120 python3 -m glint.bench.measure_visibility --size $HD --out $B \
  --scenes living-room planar-classes cornell-box material-classes many-10 | tee $O/vis.md

step "3 mirror passes in a rectangle, built-in scenes"
timeout 60 python3 -m glint.bench.measure_mirror_scissor --size $HD --out $B --scenes living-room planar-classes \
  | tee $O/scissor.md
timeout 60 python3 -m glint.bench.measure_mirror_resolution --size $HD --out $B --scenes living-room planar-classes \
  | tee -a $O/scissor.md  # eight files at most: the lower resolution goes with the rectangle

step "4 bakes: the staircase (draft, cube maps on this GPU), many-10000"
for n in $S many-10000; do
  t=$SECONDS
  timeout 150 python3 -c "
import sys; from pathlib import Path; from glint.bench.measure_draw_count import bake_for
from glint.core.bake_dir import Bake
st = Bake(bake_for(sys.argv[1], Path(sys.argv[2]))).model.statistics  # the bake's stages on this machine
print({k: {f: v[f] for f in ('seconds', 'trace_seconds', 'phase_seconds', 'rays_per_second', 'tiles', 'rendered', 'processes') if f in v}
       for k, v in st.data.items() if isinstance(v, dict)})" $n $B 2>&1 | tail -3
  echo "$n: rc ${PIPESTATUS[0]}, $((SECONDS - t)) s"
done

step "5 frame times, staircase and 10 / 10,000 boxes, both ways"
timeout 130 python3 -m glint.bench.measure_frame_times --bake-root $B --quality draft --gbuffer raster,visibility \
  --supersample 1 --sizes $HD --scenes $S,many-10,many-10000 --out /tmp/ft2
cp /tmp/ft2/frame_times.md $O/ft2.md; cp /tmp/ft2/frame_times.json $O/ft2.json

step "6 visibility against raster and the rectangle, staircase"
timeout 50 python3 -m glint.bench.measure_visibility --size $HD --out $B --scenes $S | tee -a $O/vis.md
timeout 40 python3 -m glint.bench.measure_mirror_scissor --size $HD --out $B --scenes $S | tee -a $O/scissor.md

step "7 the counted multi-draw against every command to the driver"
timeout 60 python3 -m glint.bench.measure_draw_count --size $HD --out $B --scenes living-room many-10 many-10000 \
  | tee $O/drawcount.md
step "done"
