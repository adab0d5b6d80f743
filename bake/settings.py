"""Bake settings: quality presets, overridden by the sidecar's [bake] table, then the command line."""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass, fields, replace

from glint.bake.executor import check_scheduler_address
from glint.core.errors import GlintError

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


@dataclass(frozen=True)
class BakeSettings:
    quality: str = "preview"
    samples: int = 128
    texels_per_metre: float = 16.0
    padding: int = 2  # texels between charts, so bilinear look-ups never mix charts
    max_page_size: int = 2048
    max_depth: int = 64
    denoise: bool = True
    backface_threshold: float = 0.2  # texels seeing more back faces than this are invalid (inside walls)
    seed: int = 0
    jobs: int = 0  # 0 = one per core
    # A Dask scheduler's address (`tcp://HOST:PORT`) or `local:N` (bake/executor.py DaskExecutor); None: local processes
    scheduler: str | None = None
    # The cube-map probes (bake/cubemap.py "Probes"): sharing factor (0: one probe per object) and budget.
    probe_sharing: float = 1.0
    cubemap_budget: int = 2048  # probes
    cubemap_budget_mib: float = 512.0

    @property
    def workers(self) -> int:
        return self.jobs if self.jobs > 0 else (os.cpu_count() or 1)

    def transport_dict(self) -> dict:
        """The settings the light maps depend on (jobs and the scheduler do not change a result; the
        probes' settings change only the cube-map plans, whose hashes hold what they decide)."""
        d = asdict(self)
        for k in (*EXECUTION_SETTINGS, "quality", *PROBE_SETTINGS):
            d.pop(k)
        return d


def _typed(key: str, value, kind: type, where: str):
    if kind is str:
        if not isinstance(value, str):
            raise GlintError(f"{where}: {key} must be a string (got {value!r})")
        return value
    ok = (isinstance(value, bool) if kind is bool
          else isinstance(value, (int, float)) and not isinstance(value, bool) and float(value) == float(value)
          and (kind is float or float(value).is_integer()))
    if not ok:
        raise GlintError(f"{where}: {key} must be {'true or false' if kind is bool else 'a whole number' if kind is int else 'a number'}"
                         f" (got {value!r})")
    return kind(value)


def resolve_settings(sidecar: dict | None = None, **cli) -> BakeSettings:
    """Preset of the chosen quality, then sidecar [bake] keys, then explicit command-line values."""
    sidecar = dict(sidecar or {})
    quality = cli.get("quality") or sidecar.get("quality") or "preview"
    if quality not in PRESETS:
        raise GlintError(f"unknown quality '{quality}' (choose {', '.join(PRESETS)})")
    values = dict(PRESETS[quality], quality=quality)
    names = {f.name for f in fields(BakeSettings)}
    types = {f.name: type(getattr(BakeSettings(), f.name)) for f in fields(BakeSettings)}
    types["scheduler"] = str  # its default, None, says no type
    for where, source in (("[bake] in the sidecar", sidecar), ("command line", cli)):
        for key, value in source.items():
            if value is None or key == "quality":
                continue
            if key not in names or (source is sidecar and key in COMMAND_LINE_ONLY):
                continue  # unknown sidecar keys are reported by the sidecar reader
            values[key] = _typed(key, value, types[key], where)
    settings = replace(BakeSettings(), **values)
    if settings.samples < 1:
        raise GlintError(f"samples must be at least 1 (got {settings.samples})")
    if not settings.texels_per_metre > 0:
        raise GlintError(f"texels per metre must be positive (got {settings.texels_per_metre})")
    if not settings.probe_sharing >= 0:
        raise GlintError(f"probe_sharing must be 0 (a probe per object) or more (got {settings.probe_sharing})")
    if settings.cubemap_budget < 1 or not settings.cubemap_budget_mib > 0:
        raise GlintError(f"cubemap_budget and cubemap_budget_mib must be positive (got {settings.cubemap_budget}, "
                         f"{settings.cubemap_budget_mib})")
    if settings.jobs < 0:
        raise GlintError(f"jobs must be 0 (all cores) or more (got {settings.jobs})")
    if settings.scheduler is not None:
        check_scheduler_address(settings.scheduler)
    return settings
