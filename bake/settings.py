"""Bake settings: quality presets, overridden by the sidecar's [bake] table, then the command line."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

from glint.parallel.cpus import usable_cpus
from glint.parallel.executor import check_scheduler_address
from glint.bake.sidecar_schema import BAKE

# samples: hemisphere paths per texel; texels_per_metre: light-map resolution.
# Measured times per preset are in docs/BAKE.md.
PROBE_SETTINGS = ("probe_sharing", "cubemap_budget", "cubemap_budget_mib")
# Where the bake runs, never what it makes: left out of the hashes and the manifest (transport_dict).
EXECUTION_SETTINGS = ("jobs", "scheduler")
# Settings of the machine that runs the command, not of the scene: not read from a sidecar's [bake].
COMMAND_LINE_ONLY = ("scheduler",)
PRESETS = {
    "draft": {"samples": 32, "texels_per_metre": 8.0},
    "preview": {"samples": 128, "texels_per_metre": 16.0},
    "final": {"samples": 1024, "texels_per_metre": 32.0},
}


def _default(key: str):
    return BAKE[key].default


@dataclass(frozen=True)
class BakeSettings:
    """The bake's settings; each field's default, range and meaning: bake/sidecar_schema.py BAKE."""
    quality: str = _default("quality")
    samples: int = _default("samples")
    texels_per_metre: float = _default("texels_per_metre")
    padding: int = _default("padding")  # texels between charts, so bilinear look-ups never mix charts
    max_page_size: int = _default("max_page_size")
    max_depth: int = _default("max_depth")
    # paths per texel at most, as a multiple of `samples`, where adaptive sampling finds a texel
    # undersampled (bake/lightmap.py "Adaptive sampling"); 1: every texel gets `samples` paths
    adaptive_samples: int = _default("adaptive_samples")
    denoise: bool = _default("denoise")
    backface_threshold: float = _default("backface_threshold")
    seed: int = _default("seed")
    jobs: int = _default("jobs")  # 0 = one per usable CPU (parallel/cpus.py)
    # A Dask scheduler's address (`tcp://HOST:PORT`) or `local:N` (parallel/executor.py DaskExecutor);
    # None: local processes
    scheduler: str | None = _default("scheduler")
    # The cube-map probes (bake/cubemap.py "Probes"): sharing factor (0: one probe per object) and budget.
    probe_sharing: float = _default("probe_sharing")
    cubemap_budget: int = _default("cubemap_budget")  # probes
    cubemap_budget_mib: float = _default("cubemap_budget_mib")

    @property
    def workers(self) -> int:
        return self.jobs if self.jobs > 0 else usable_cpus()

    def transport_dict(self) -> dict:
        """The settings the light maps depend on (jobs and the scheduler do not change a result; the
        probes' settings change only the cube-map plans, whose hashes hold what they decide)."""
        d = asdict(self)
        for k in (*EXECUTION_SETTINGS, "quality", *PROBE_SETTINGS):
            d.pop(k)
        return d


def resolve_settings(sidecar: dict | None = None, **cli) -> BakeSettings:
    """Preset of the chosen quality, then sidecar [bake] keys, then explicit command-line values; each
    value checked by its key's rule (bake/sidecar_schema.py BAKE), the command line's named as its option."""
    sidecar = dict(sidecar or {})
    names = {f.name for f in fields(BakeSettings)}
    sources = (("[bake]", sidecar), ("", cli))
    quality = BAKE["quality"].default
    for where, source in sources:
        if source.get("quality") is not None:
            quality = BAKE["quality"].check(source["quality"], where or "--quality", "quality")
    values = dict(PRESETS[quality], quality=quality)
    for where, source in sources:
        for key, value in source.items():
            if value is None or key == "quality":
                continue
            if key not in names or (source is sidecar and key in COMMAND_LINE_ONLY):
                continue  # unknown sidecar keys are reported by the sidecar reader
            values[key] = BAKE[key].check(value, where, key) if where else \
                BAKE[key].check(value, "--" + key.replace("_", "-"), "")
    settings = replace(BakeSettings(), **values)
    if settings.scheduler is not None:
        check_scheduler_address(settings.scheduler)
    return settings
