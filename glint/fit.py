"""`glint fit FILE --name NAME`: fit the section 3.3 material model to a measured BRDF (thesis 3.4.1).

    glint fit gold-metallic-paint.binary --name "Gold paint" -o room.glint.toml
    glint fit floor.csv --name Floor --lobes 2 --plots fit-plots/

FILE is a MERL `.binary` file or an isotropic `.csv` table (bake/merl.py documents both). The fit
(bake/brdf_fit.py) prints the material, its error and the directional albedo of data and fit per
view angle (as the thesis' Table 3.1 gives error and albedo). With -o it writes the material into
the sidecar as [materials."NAME"] kd and lobes, in place (bake/edits.py: comments, order and
every other key stay; a material of that name gets its kd and lobes replaced, its other keys such
as emission kept). A file that is not a glint sidecar (a name not ending in .glint.toml, or tables
a sidecar does not have) is refused, never overwritten. Without -o the table is printed as TOML.
--plots DIR writes PNG plots of data against fit in the plane of incidence (the thesis' Fig. 3.12;
needs matplotlib, `pip install 'glint[bench]'`).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from glint.core.errors import GlintError

METHODS = ("multistart", "hierarchical")  # bake/brdf_fit.py METHODS, default first (not imported: start-up)
PLOT_THETA_I = (0, 15, 30, 45, 60, 75)  # degrees: one panel each (thesis Fig. 3.12)


def add_fit_options(p: argparse.ArgumentParser) -> None:
    """`glint fit`'s options, on the parser glint/cli.py made for it."""
    p.description = ("Fit the material model (kd and one or two Beckmann lobes with Kurt's alpha, thesis "
                     "section 3.3) to a measured BRDF: a MERL .binary file or a .csv table of "
                     "theta_i,theta_o,phi_d,r,g,b. Prints the fit and the albedo per view angle; -o writes it "
                     "into a sidecar as [materials.\"NAME\"].")
    p.add_argument("file", metavar="FILE", type=Path, help="the measured BRDF (.binary MERL or .csv table)")
    p.add_argument("--name", required=True, help="the glTF material name the fit is for")
    p.add_argument("-o", "--output", type=Path, metavar="SIDECAR.glint.toml",
                   help="sidecar to write [materials.\"NAME\"] into (created if absent, edited in place)")
    p.add_argument("--lobes", type=int, choices=(1, 2), default=1, help="reflection lobes to fit (default 1)")
    p.add_argument("--method", choices=METHODS, default=METHODS[0],
                   help="parameter search: multi-start L-BFGS-B (default) or the thesis' hierarchical brute force")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write PNG plots of data against fit into DIR")
    p.set_defaults(run=run_fit)


def check_output(path: Path) -> None:
    """Refuse before any work a sidecar path glint must not write (module docstring)."""
    from glint.bake.sidecar import SUFFIX, TABLES, parse_toml, read_sidecar_text

    if not path.name.endswith(SUFFIX):
        raise GlintError(f"-o {path}: glint writes fits only into a sidecar NAME{SUFFIX}")
    text = read_sidecar_text(path)
    if text is None:
        if not path.parent.is_dir():
            raise GlintError(f"-o {path}: no such directory {path.parent}")
        return
    other = [key for key in parse_toml(text, path) if key not in TABLES]
    if other:
        raise GlintError(f"-o {path}: not a glint sidecar (it has {', '.join(map(repr, other))}); "
                         "refusing to write into it")


def check_plots() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise GlintError("--plots needs matplotlib: pip install 'glint[bench]'") from None


def run_fit(args) -> int:
    from tqdm import tqdm

    from glint.bake.brdf_fit import BrdfData, expected_evaluations, fit
    from glint.bake.merl import read_brdf_file

    if not args.name.strip():
        raise GlintError("--name must name a material")
    if args.output is not None:
        check_output(args.output)
    if args.plots is not None:
        check_plots()
    measured = read_brdf_file(args.file)
    data = BrdfData.from_function(measured.evaluate, name=args.file.name)
    total = expected_evaluations(args.lobes, data.transmission, args.method)
    with tqdm(total=total, desc="fit", unit="candidate", disable=not sys.stderr.isatty(), leave=False) as bar:
        result = fit(data, args.lobes, method=args.method, progress=bar.update)
    print(report(result, args.name))
    table = sidecar_values(result)
    if args.output is not None:
        write_fit(args.output, args.name, table)
    else:
        print(toml_text(args.name, table))
    if args.plots is not None:
        print(f"plots: {plot_fit(args.plots, measured.evaluate, result, args.name)}")
    return 0


def _num(v: float) -> float:
    """Five significant digits: what a sidecar needs, read back as written."""
    return float(f"{float(v):.5g}")


def sidecar_values(result) -> dict:
    """[materials."NAME"]'s kd and lobes of a fit (the sidecar's keys, bake/material_mapping.py)."""
    return {"kd": [_num(c) for c in result.kd],
            "lobes": [{"kind": lobe.kind, "ks": [_num(c) for c in lobe.ks], "mx": _num(lobe.mx), "my": _num(lobe.my),
                       "r0": _num(lobe.r0), "alpha": _num(lobe.alpha)} for lobe in result.lobes]}


def write_fit(path: Path, name: str, values: dict) -> None:
    from glint.bake.edits import save_sidecar_file
    from glint.bake.sidecar import parse_toml, read_sidecar_text

    text = read_sidecar_text(path)
    existed = text is not None and name in parse_toml(text, path).get("materials", {})
    save_sidecar_file(path, [(("materials", name, key), values[key]) for key in ("kd", "lobes")])
    print(f"{'replaced kd and lobes of' if existed else 'wrote'} [materials.\"{name}\"] in {path}")


def toml_text(name: str, values: dict) -> str:
    from glint.bake.edits import format_assignment

    return "\n".join([f"[materials.{format_assignment((name,), 0).rsplit(' = ', 1)[0]}]"]
                     + [format_assignment((key,), values[key]) for key in ("kd", "lobes")])


def report(result, name: str) -> str:
    """The fit as the thesis' Table 3.1 gives it (parameters, error, albedo), then albedo per view angle."""
    import numpy as np

    grey = lambda c: float(np.mean(c))  # noqa: E731
    lines = [f"material '{name}': {len(result.lobes)} lobe(s), {result.method} search, "
             f"{result.evaluations} candidates, {result.seconds:.1f} s",
             f"{'':>6} {'kd':>6} {'ks':>6} {'mx':>7} {'my':>7} {'r0':>6} {'alpha':>6}"]
    for k, lobe in enumerate(result.lobes):
        kd = f"{grey(result.kd):6.3f}" if k == 0 else f"{'':>6}"
        lines.append(f"{lobe.kind:>7}{kd} {grey(lobe.ks):6.3f} {lobe.mx:7.4f} {lobe.my:7.4f} {lobe.r0:6.3f} "
                     f"{lobe.alpha:6.3f}")
    lines.append(f"error {result.error:.4g} (relative least squares: 0 exact, 1 as far as black); "
                 f"albedo at normal incidence: data {grey(result.albedo_data[0]):.3f}, fit {grey(result.albedo_fit[0]):.3f}")
    lines.append("view angle  albedo data    fit   error")
    for t, a, b in zip(np.degrees(result.theta_o), result.albedo_data, result.albedo_fit):
        rel = (grey(b) - grey(a)) / max(grey(a), 1e-4)
        lines.append(f"{t:8.0f}°  {grey(a):11.3f} {grey(b):6.3f} {rel:+6.1%}")
    lines.append(f"largest albedo error up to 80°: {result.albedo_error:.1%}")
    return "\n".join(lines)


def plot_fit(folder: Path, evaluate, result, name: str) -> Path:
    """PNG of the data against the fit, f cos(theta_i) in the plane of incidence for PLOT_THETA_I (cube root,
    as the thesis' Fig. 3.12); returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from glint.core import bsdf
    from glint.core.atomic import atomic_path

    folder.mkdir(parents=True, exist_ok=True)
    theta_o = np.radians(np.linspace(-89.0, 89.0, 357))
    fig, axes = plt.subplots(2, 3, figsize=(12, 7), sharex=True)
    for ax, ti in zip(axes.ravel(), PLOT_THETA_I):
        t = np.radians(ti)
        wi = np.broadcast_to(np.array([np.sin(t), 0.0, np.cos(t)]), theta_o.shape + (3,))
        wo = np.stack([-np.sin(theta_o), np.zeros_like(theta_o), np.cos(theta_o)], axis=-1)  # + = mirror side
        measured = np.asarray(evaluate(wi, wo), float).mean(axis=-1)
        measured = np.where(np.isfinite(measured) & (measured >= 0.0), measured, np.nan)
        fitted = bsdf.bsdf(wi, wo, result.kd, result.lobes).mean(axis=-1)
        ax.plot(np.degrees(theta_o), np.cbrt(measured * np.cos(t)), color="tab:green", label="data")
        ax.plot(np.degrees(theta_o), np.cbrt(fitted * np.cos(t)), color="tab:red", label="fit")
        ax.set_title(f"theta_i = {ti}°")
        ax.set_xlabel("theta_o (degrees; + mirror side)")
    axes[0, 0].set_ylabel("(f cos theta_i)^(1/3)")
    axes[0, 0].legend()
    fig.suptitle(f"{name}: data (green) and fit (red) in the plane of incidence")
    fig.tight_layout()
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "material"
    out = folder / f"fit-{safe}.png"
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png", dpi=80)
    plt.close(fig)
    return out
