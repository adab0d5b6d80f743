"""Measured BRDFs from files: the MERL database's binary format and an isotropic CSV table.

MERL binary (Matusik et al. 2003, MERL's BRDFRead.cpp): three int32 dimensions (90, 90, 180),
then 3 x 90 x 90 x 180 float64 values, channel-major (all red, then green, then blue), each
multiplied by 1/1500, 1.15/1500 and 1.66/1500 for R, G and B; negative values are directions
that were not measured. A value is indexed by Rusinkiewicz's half/difference angles
(theta_h, theta_d, phi_d), phi_h ignored (isotropic), flat index
phi_d_index + 180 (theta_d_index + 90 theta_h_index), with
  theta_h_index = floor(sqrt(theta_h / (pi/2)) x 90)   (non-linear: dense near the specular peak),
  theta_d_index = floor(theta_d / (pi/2) x 90),
  phi_d_index   = floor(phi_d / pi x 180), phi_d + pi first where it is negative (reciprocity),
each clamped to its range. `write_merl` writes a BRDF at each bin's centre in those index
coordinates (so the reader's nearest-bin lookup is unbiased), -1 where wi or wo is below the
surface.

Isotropic CSV table (`*.csv`): a header line `theta_i,theta_o,phi_d,r,g,b`, then one row per
sample: the incident and view angles from the normal and the azimuth between them, |phi_i - phi_o|
folded into [0, 180] (degrees; 180: wi on the mirror side of the plane of incidence, 0: on the
viewer's side), and the BRDF (1/sr, linear RGB; negative: not measured).
The rows must form a full grid (every combination of the listed theta_i, theta_o and phi_d
values); it is interpolated linearly, and is missing outside its range. Reflection only.

`read_brdf_file` reads either (by the file's suffix) into a `MeasuredBrdf`, whose `evaluate(wi, wo)`
is what bake/brdf_fit.py `BrdfData.from_function` takes. Bad files are one line (GlintError).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from glint.core.errors import GlintError

RES_THETA_H, RES_THETA_D, RES_PHI_D = 90, 90, 180  # MERL's dimensions (BRDF_SAMPLING_RES_PHI_D / 2)
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])  # R, G, B
HEADER = ("theta_i", "theta_o", "phi_d", "r", "g", "b")
MISSING = -1.0


@dataclass
class MeasuredBrdf:
    """A BRDF read from a file: `evaluate(wi, wo) -> (..., 3)` (negative or NaN where it has no value)."""

    name: str
    kind: str  # "merl" or "table"
    evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray]


# ----------------------------------------------------------------------------- half / difference angles

def _rotate(v, axis, angle):
    """Rodrigues' rotation of vectors v (..., 3) about the unit `axis` (3,) by `angle` (...)."""
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    axis = np.asarray(axis, float)
    return v * c + axis * (v @ axis)[..., None] * (1.0 - c) + np.cross(axis, v) * s


def half_diff(wi, wo):
    """Rusinkiewicz's (theta_h, phi_h, theta_d, phi_d) of unit vectors wi, wo (..., 3)."""
    wi, wo = np.asarray(wi, float), np.asarray(wo, float)
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    theta_h = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    phi_h = np.arctan2(h[..., 1], h[..., 0])
    d = _rotate(_rotate(wi, (0.0, 0.0, 1.0), -phi_h), (0.0, 1.0, 0.0), -theta_h)
    return theta_h, phi_h, np.arccos(np.clip(d[..., 2], -1.0, 1.0)), np.arctan2(d[..., 1], d[..., 0])


def from_half_diff(theta_h, theta_d, phi_d, phi_h=0.0):
    """(wi, wo) of half/difference angles: the inverse of `half_diff`."""
    theta_h, theta_d, phi_d, phi_h = np.broadcast_arrays(*(np.asarray(a, float) for a in
                                                           (theta_h, theta_d, phi_d, phi_h)))
    d = np.stack([np.sin(theta_d) * np.cos(phi_d), np.sin(theta_d) * np.sin(phi_d), np.cos(theta_d)], axis=-1)
    wi = _rotate(_rotate(d, (0.0, 1.0, 0.0), theta_h), (0.0, 0.0, 1.0), phi_h)
    h = np.stack([np.sin(theta_h) * np.cos(phi_h), np.sin(theta_h) * np.sin(phi_h), np.cos(theta_h)], axis=-1)
    wo = 2.0 * np.sum(wi * h, axis=-1, keepdims=True) * h - wi
    return wi, wo


def merl_index(theta_h, theta_d, phi_d):
    """The flat index (per channel) of MERL's table for angles in radians (module docstring)."""
    theta_h, theta_d, phi_d = (np.asarray(a, float) for a in (theta_h, theta_d, phi_d))
    ih = np.floor(np.sqrt(np.maximum(theta_h, 0.0) / (np.pi / 2)) * RES_THETA_H)
    ih = np.clip(ih, 0, RES_THETA_H - 1).astype(np.int64)
    idd = np.clip(np.floor(theta_d / (np.pi / 2) * RES_THETA_D), 0, RES_THETA_D - 1).astype(np.int64)
    phi = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)
    ip = np.clip(np.floor(phi / np.pi * RES_PHI_D), 0, RES_PHI_D - 1).astype(np.int64)
    return ip + RES_PHI_D * (idd + RES_THETA_D * ih)


# ----------------------------------------------------------------------------- MERL binary

@dataclass
class MerlTable:
    """A MERL BRDF: values (3, 90 x 90 x 180), already scaled to 1/sr; negative = not measured."""

    values: np.ndarray

    def evaluate(self, wi, wo) -> np.ndarray:
        """(..., 3) by nearest bin (as MERL's lookup_brdf_val); negative where not measured or where
        wi or wo is below the surface."""
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        th, _, td, pd = half_diff(wi, wo)
        out = self.values[:, merl_index(th, td, pd)]  # (3, ...)
        out = np.moveaxis(out, 0, -1)
        below = (wi[..., 2] <= 0.0) | (wo[..., 2] <= 0.0)
        return np.where(below[..., None], MISSING, out)


def read_merl(path: Path) -> MerlTable:
    """A MERL .binary file; GlintError (one line) for a wrong size, dimensions, NaN or no value."""
    path = Path(path)
    n = RES_THETA_H * RES_THETA_D * RES_PHI_D
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise GlintError(f"{path.name}: cannot read: {err.strerror or err}") from None
    if len(raw) < 12:
        raise GlintError(f"{path.name}: not a MERL BRDF file (only {len(raw)} bytes)")
    dims = tuple(int(v) for v in np.frombuffer(raw[:12], "<i4"))
    if dims != (RES_THETA_H, RES_THETA_D, RES_PHI_D):
        raise GlintError(f"{path.name}: not a MERL BRDF file (dimensions {dims}, expected "
                         f"{(RES_THETA_H, RES_THETA_D, RES_PHI_D)})")
    if len(raw) != 12 + 8 * 3 * n:
        raise GlintError(f"{path.name}: a MERL BRDF file has {12 + 8 * 3 * n} bytes, this one {len(raw)} "
                         "(truncated or padded)")
    values = np.frombuffer(raw[12:], "<f8").reshape(3, n) * SCALE[:, None]
    if not np.all(np.isfinite(values)):
        raise GlintError(f"{path.name}: {int(np.sum(~np.isfinite(values)))} values are NaN or infinite")
    if not np.any(np.all(values >= 0.0, axis=0)):
        raise GlintError(f"{path.name}: no measured value (every value is negative: not measured)")
    return MerlTable(values)


def bin_centres():
    """(theta_h, theta_d, phi_d) at every bin's centre in index coordinates, in the file's order."""
    ih, idd, ip = np.meshgrid(np.arange(RES_THETA_H), np.arange(RES_THETA_D), np.arange(RES_PHI_D), indexing="ij")
    theta_h = ((ih + 0.5) / RES_THETA_H) ** 2 * (np.pi / 2)  # the inverse of the sqrt mapping
    theta_d = (idd + 0.5) / RES_THETA_D * (np.pi / 2)
    phi_d = (ip + 0.5) / RES_PHI_D * np.pi
    return theta_h.ravel(), theta_d.ravel(), phi_d.ravel()


def write_merl(path: Path, brdf: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Path:
    """Write `brdf(wi, wo) -> (..., 3)` as a MERL .binary file at the bins' centres; MISSING below the
    surface. (For tests and the fit-back check; the real database comes from MERL.)"""
    wi, wo = from_half_diff(*bin_centres())
    rgb = np.asarray(brdf(wi, wo), float)
    below = (wi[..., 2] <= 0.0) | (wo[..., 2] <= 0.0)
    rgb = np.where(below[..., None], MISSING * SCALE, rgb)  # stored as -1 after the division
    data = (rgb.T / SCALE[:, None]).astype("<f8")  # channel-major
    with open(path, "wb") as f:
        f.write(np.array([RES_THETA_H, RES_THETA_D, RES_PHI_D], "<i4").tobytes())
        f.write(data.tobytes())
    return Path(path)


# ----------------------------------------------------------------------------- the CSV table

def read_table(path: Path) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The isotropic CSV table (module docstring) as a callable (linear interpolation, NaN outside)."""
    from scipy.interpolate import RegularGridInterpolator

    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as err:
        raise GlintError(f"{path.name}: cannot read: {err}") from None
    rows = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    if not rows or tuple(c.strip() for c in rows[0].split(",")) != HEADER:
        raise GlintError(f"{path.name}: a BRDF table starts with the header line {','.join(HEADER)}")
    try:
        table = np.array([[float(c) for c in row.split(",")] for row in rows[1:]], float)
    except ValueError as err:
        raise GlintError(f"{path.name}: not a number in the table ({err})") from None
    if table.ndim != 2 or table.shape[0] == 0 or table.shape[1] != len(HEADER):
        raise GlintError(f"{path.name}: every row needs {len(HEADER)} numbers ({','.join(HEADER)})")
    if not np.all(np.isfinite(table)):
        raise GlintError(f"{path.name}: the table has NaN or infinite values")
    angles, rgb = table[:, :3], table[:, 3:]
    lo, hi = np.array([0, 0, 0]), np.array([90, 90, 180])
    if np.any(angles < lo) or np.any(angles > hi):
        raise GlintError(f"{path.name}: theta_i and theta_o must be within 0-90 degrees and phi_d within 0-180")
    if not np.any(np.all(rgb >= 0.0, axis=-1)):
        raise GlintError(f"{path.name}: no measured value (every value is negative)")
    axes = [np.unique(angles[:, d]) for d in range(3)]
    shape = tuple(len(a) for a in axes)
    if np.prod(shape) != len(table) or any(n < 2 for n in shape):
        raise GlintError(f"{path.name}: the rows must form a full grid of at least 2 theta_i x 2 theta_o x "
                         f"2 phi_d values ({len(table)} rows for {' x '.join(map(str, shape))} values)")
    idx = tuple(np.searchsorted(axes[d], angles[:, d]) for d in range(3))
    grid = np.full(shape + (3,), np.nan)
    grid[idx] = rgb
    if np.any(np.isnan(grid)):
        raise GlintError(f"{path.name}: a (theta_i, theta_o, phi_d) combination appears twice")
    grid = np.where(grid >= 0.0, grid, np.nan)  # negative: not measured
    interp = RegularGridInterpolator(axes, grid, bounds_error=False, fill_value=np.nan)

    def evaluate(wi, wo):
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        ti = np.degrees(np.arccos(np.clip(wi[..., 2], -1.0, 1.0)))
        to = np.degrees(np.arccos(np.clip(wo[..., 2], -1.0, 1.0)))
        # azimuth between wi and wo: 0 on the same side, 180 across (the mirror direction's)
        dphi = np.degrees(np.abs(np.arctan2(wi[..., 1], wi[..., 0]) - np.arctan2(wo[..., 1], wo[..., 0])))
        dphi = np.where(dphi > 180.0, 360.0 - dphi, dphi)
        out = interp(np.stack([ti, to, dphi], axis=-1).reshape(-1, 3)).reshape(wi.shape[:-1] + (3,))
        return np.where(((wi[..., 2] > 0.0) & (wo[..., 2] > 0.0))[..., None], out, np.nan)

    return evaluate


# ----------------------------------------------------------------------------- one entry point

def read_brdf_file(path: Path) -> MeasuredBrdf:
    """A MERL `.binary` file or an isotropic `.csv` table (module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise GlintError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".binary":
        return MeasuredBrdf(path.stem, "merl", read_merl(path).evaluate)
    if suffix == ".csv":
        return MeasuredBrdf(path.stem, "table", read_table(path))
    raise GlintError(f"{path.name}: unknown BRDF file type '{suffix}' (a MERL .binary file or a .csv table "
                     f"with the columns {','.join(HEADER)})")
