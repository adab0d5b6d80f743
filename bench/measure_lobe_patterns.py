"""The measurement behind viewer/lobe_patterns.py's rules: which pattern, how many samples.

    python3 -m glint.bench.measure_lobe_patterns                 # the three tables of docs/BENCHMARKS.md
    python3 -m glint.bench.measure_lobe_patterns samples --pattern ring
    python3 -m glint.bench.measure_lobe_patterns samples --pattern line --ms 0.02,0.03,0.05
    python3 -m glint.bench.measure_lobe_patterns threshold
    python3 -m glint.bench.measure_lobe_patterns fis            # patterns against filtered importance sampling
    python3 -m glint.bench.measure_lobe_patterns albedo         # the albedo-normalised mean's weights
    python3 -m glint.bench.measure_lobe_patterns samples --seed 5 --envs 30   # another set of environments

Set-up (numpy only, no GPU; the functions measured are viewer/lobe_patterns.py's and
core/bsdf.py's, i.e. the float64 twins of the shaders):
- Environment: 6 spherical Gaussians G(w) = a exp(lam (mu.w - 1)) at random directions, lam
  log-uniform in [1, 1e4], each of unit energy (a = lam / 2 pi): sky-like light and lamps of
  ~0.6 degrees, the small ones bright, as in a room.
- Views theta_o = 0, 25, 45, 45, 60, 70, 80 degrees (with fixed azimuths), r0 = 0.5, alpha = 0.
- Reference: the lobe's integral of L f cos by QMC with multiple importance sampling (balance
  heuristic) of the lobe's own samples (Eq. 4.5-4.9) and each Gaussian's, 2 x 8192 per Gaussian.
- Estimate: Eq. 4.25 (or 4.24) over `pattern_xi(kind, n)`, each look-up filtered as its MIP level
  filters it: the environment convolved exactly with a normalised vMF kernel of the sample's
  solid angle A / n (A = `lobe_ellipse_area`; variance-matched, lam_f = 12 n / A; at most one
  cube face, 4 pi / 6).
- Error per case (environment x view): |estimate - reference| / reference.

`samples` prints the 75th / 90th percentiles per roughness m and n (isotropic m_x = m_y = m with
the ring, or anisotropic m_y = 10 m_x = m with the line) and the smallest n that keeps them
within 1% / 2.5% (`samples_for_lobe`'s criterion); `threshold` prints ring against line at the
same n over anisotropy ratios (sum of errors over sum of references, %). The defaults are the
runs quoted in docs/BENCHMARKS.md ("Lobe patterns: how the rules were measured"), behind the
rules of viewer/lobe_patterns.py: seed 11 with 40 environments, seed 21 with 30.

`albedo` (not part of `all`; docs/BENCHMARKS.md, "The walkthrough's albedo normalisation"): the
walkthrough's albedo-normalised estimate A x sum w L / sum w (viewer/lobe_albedo.py; A by
core/bsdf.py lobe_albedo) with the weights w = p cos, f cos or v = f cos / p, beside Eq. 4.25 and
4.24, for the lobes the glTF mapping fits (Kurt's alpha ~ 1/2: metals of roughness 0.3 and 0.5,
dielectrics of 0.25 and 0.4), an alpha = 0 lobe of m = 0.1 and an anisotropic line (m 0.02 x 0.2,
alpha 0.5), at views of 0-82 degrees (ALBEDO_VIEWS); median, 75th and 90th percentile of the error.

`fis` (not part of `all`; docs/BENCHMARKS.md) puts the patterns beside Colbert and Krivanek's
filtered importance sampling at the same n, in the same model: Eq. 4.4 weights f cos / p over n
lobe samples (Eq. 4.5-4.9), each look-up filtered over the sample's solid angle 1 / (n p) (their
MIP level 0.5 log2(omega_s / omega_p) as a vMF kernel, as the patterns' A / n above), with two
point sets: the shader's (shaders/specular.glsl: R2 points 0 .. n-1, not rotated, 24-bit as
`r2_point`) and the centred Hammersley set ((i + 1/2) / n, radical inverse of i), and the
unfiltered per-pixel QMC estimate (Eq. 4.4, the R2 points of 64 per-pixel rotations).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from glint.core import bsdf
from glint.core.atomic import atomic_path
from glint.viewer import lobe_patterns as P

NS = (1, 3, 5, 7, 9, 11, 15, 19)       # measured
SHOWN = (1, 3, 5, 7, 11, 19)           # columns of the printed tables
VIEWS = ((0, 0.4), (25, 1.2), (45, 0.4), (45, 2.0), (60, 0.9), (70, 0.4), (80, 1.3))  # (theta_o deg, phi_o)
OMEGA_MAX = 4 * np.pi / 6              # the coarsest useful MIP level: a whole cube face
REFERENCE_SAMPLES = 1 << 13
GAUSSIANS = 6
LAMBDA_RANGE = (1.0, 1e4)
RULE = (1.0, 2.5)                      # 75th and 90th percentile limits (%) of samples_for_lobe
DEFAULT_MS = {"ring": (0.01, 0.02, 0.03, 0.05, 0.1, 0.2), "line": (0.02, 0.03, 0.05, 0.1, 0.2)}
PATTERN = {"ring": ("ring", 1.0), "line": ("line_y", 10.0)}   # pattern kind, m_y / m_x


# -- environments ----------------------------------------------------------------------------------
def sph(theta, phi):
    theta, phi = np.broadcast_arrays(theta, phi)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def environment(rng, k=GAUSSIANS, lam_range=LAMBDA_RANGE):
    """(mu (k, 3), lam (k,), a (k,)): k unit-energy spherical Gaussians at random directions."""
    lam = np.exp(rng.uniform(np.log(lam_range[0]), np.log(lam_range[1]), k))
    z = rng.uniform(-1, 1, k)
    ph = rng.uniform(0, 2 * np.pi, k)
    mu = np.stack([np.sqrt(1 - z * z) * np.cos(ph), np.sqrt(1 - z * z) * np.sin(ph), z], -1)
    return mu, lam, lam / (2 * np.pi)


def radiance(w, env, lam_f=None):
    """Radiance along unit directions w (..., 3); with lam_f, convolved exactly with a normalised
    vMF kernel K(w.v) = c exp(lam_f (w.v - 1)), c = lam_f / (2 pi (1 - exp(-2 lam_f)))."""
    mu, lam, a = env
    d = w @ mu.T
    if lam_f is None:
        return np.sum(a * np.exp(lam * (d - 1)), -1)
    lf = np.asarray(lam_f, dtype=float)[..., None]
    r = np.sqrt(np.maximum(lam ** 2 + lf ** 2 + 2 * lam * lf * d, 1e-300))
    c = lf / (2 * np.pi * (-np.expm1(-2 * lf)))
    return np.sum(a * c * 4 * np.pi * np.exp(r - lam - lf) * (-np.expm1(-2 * r)) / (2 * r), -1)


XI = bsdf.qmc_points(REFERENCE_SAMPLES)


def reference(wo, env, mx, my, r0, alpha, kind="reflect"):
    """The lobe's integral of L f cos: MIS (balance heuristic) of lobe samples and each Gaussian's."""
    mu, lam, a = env
    x1, x2 = XI
    n = len(x1)
    wi = bsdf.sample_lobe(wo, x1, x2, mx, my, kind)
    p1 = bsdf.lobe_pdf(wi, wo, mx, my, kind)
    f1 = bsdf.lobe_value(wi, wo, mx, my, r0, alpha, kind)
    c1 = np.abs(wi[:, 2])
    total = 0.0
    for j in range(len(lam)):
        lj = lam[j]
        cos_t = 1 + np.log(x1 + (1 - x1) * np.exp(-2 * lj)) / lj   # vMF samples around mu_j
        sin_t = np.sqrt(np.maximum(1 - cos_t * cos_t, 0))
        phi = 2 * np.pi * x2
        t = np.cross(mu[j], [1.0, 0, 0] if abs(mu[j][0]) < 0.9 else [0, 1.0, 0])
        t /= np.linalg.norm(t)
        b = np.cross(mu[j], t)
        wv = (sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b + cos_t[:, None] * mu[j]
        norm = lj / (2 * np.pi * (-np.expm1(-2 * lj)))
        pdf_v = lambda w: norm * np.exp(lj * (w @ mu[j] - 1))  # noqa: E731
        G = lambda w: a[j] * np.exp(lj * (w @ mu[j] - 1))  # noqa: E731
        fv = bsdf.lobe_value(wv, wo, mx, my, r0, alpha, kind)
        cv = np.abs(wv[:, 2])
        p2 = bsdf.lobe_pdf(wv, wo, mx, my, kind)
        total += np.sum(G(wi) * f1 * c1 / (n * p1 + n * pdf_v(wi) + 1e-300))
        total += np.sum(G(wv) * fv * cv / (n * p2 + n * pdf_v(wv) + 1e-300))
    return total


def estimate(wo, env, mx, my, r0, alpha, pattern, n, weights="4.25", kind="reflect"):
    """The walkthrough's estimate: Eq. 4.25 (4.24) over the pattern, each look-up vMF-filtered."""
    xi = P.pattern_xi(pattern, n)
    wi, f, p, c = P.pattern_samples(wo, xi, mx, my, r0, alpha, kind)
    area = P.lobe_ellipse_area(wo, mx, my, kind)
    lam_f = 12.0 / np.minimum(area / n, OMEGA_MAX)
    L = radiance(wi / np.linalg.norm(wi, axis=-1, keepdims=True), env, lam_f)
    return P.pattern_estimate(L[..., None] * np.ones(3), f, p, c, weights)[..., 0]


R2_STEP = (3242174889, 2447445414)  # shaders/specular.glsl r2_point: round(2^32 / g), round(2^32 / g^2)


def r2_points(n: int, rotation=(0, 0)) -> tuple[np.ndarray, np.ndarray]:
    """Points 0 .. n-1 of the R2 sequence exactly as the shader's `r2_point` makes them."""
    i = np.arange(n, dtype=np.uint64)
    out = []
    for axis in range(2):
        x = (np.uint64(rotation[axis]) + i * np.uint64(R2_STEP[axis])) & np.uint64(0xFFFFFFFF)
        out.append(((x >> np.uint64(8)).astype(np.float64) + 0.5) / 16777216.0)
    return out[0], out[1]


def importance_estimate(wo, env, mx, my, r0, alpha, xi, filtered=True, kind="reflect"):
    """Eq. 4.4 over the lobe samples of the points xi = (xi1, xi2); with `filtered`, each look-up
    convolved over the sample's solid angle 1 / (n p) (Colbert and Krivanek's MIP level)."""
    x1, x2 = xi
    n = len(x1)
    wi = bsdf.sample_lobe(wo, x1, x2, mx, my, kind)
    pdf = bsdf.lobe_pdf(wi, wo, mx, my, kind)
    f = bsdf.lobe_value(wi, wo, mx, my, r0, alpha, kind)
    cos_i = -wi[..., 2] if kind == "transmit" else wi[..., 2]
    keep = (pdf > 0) & (cos_i > 0) & (f > 0)
    pdf_safe = np.where(keep, pdf, 1.0)
    lam_f = 12.0 / np.minimum(1.0 / (n * pdf_safe), OMEGA_MAX) if filtered else None
    L = radiance(wi / np.linalg.norm(wi, axis=-1, keepdims=True), env, lam_f)
    return float(np.sum(np.where(keep, f * cos_i / pdf_safe * L, 0.0)) / n)


def measure_fis(ms, ns, seed: int, envs: int, r0: float, log=print):
    """{method: (len(ms), cases, len(ns)) relative errors %} of the patterns (Eq. 4.25), filtered
    importance sampling with the shader's and with centred points, and unfiltered QMC."""
    todo = cases(seed, envs)
    rotations = [tuple(int(v) for v in np.random.default_rng(1000 + k).integers(0, 2 ** 32, 2)) for k in range(64)]
    methods = ("patterns", "fis-shader", "fis-centred", "qmc")
    err = {m: np.zeros((len(ms), len(todo), len(ns))) for m in methods}
    for i, m in enumerate(ms):
        started = time.perf_counter()
        for k, (wo, env) in enumerate(todo):
            ref = reference(wo, env, m, m, r0, 0.0)
            for j, n in enumerate(ns):
                est = {"patterns": estimate(wo, env, m, m, r0, 0.0, "ring", n),
                       "fis-shader": importance_estimate(wo, env, m, m, r0, 0.0, r2_points(n)),
                       "fis-centred": importance_estimate(wo, env, m, m, r0, 0.0, bsdf.qmc_points(n))}
                # unfiltered QMC: the mean error over per-pixel rotations (a pixel's expected error)
                est_qmc = [importance_estimate(wo, env, m, m, r0, 0.0, r2_points(n, rot), filtered=False)
                           for rot in rotations[:16]]
                for name, value in est.items():
                    err[name][i, k, j] = 100 * abs(value - ref) / ref
                err["qmc"][i, k, j] = 100 * np.mean(np.abs(np.array(est_qmc) - ref)) / ref
        log(f"  fis m = {m:g}: {len(todo)} cases in {time.perf_counter() - started:.1f} s")
    return err


def fis_table(ms, ns, err) -> str:
    lines = ["    median / 75th percentile error (%)  " + "".join(f"n = {n:<8}" if j == 0 else f"{n:<12}"
                                                              for j, n in enumerate(ns))]
    for i, m in enumerate(ms):
        for name, e in err.items():
            med, p75 = np.percentile(e[i], 50, axis=0), np.percentile(e[i], 75, axis=0)
            head = f"m = {m:g}" if name == "patterns" else ""
            cells = "".join(f"{_pct(a) + '/' + _pct(b):<12}" for a, b in zip(med, p75))
            lines.append(f"    {head:<10}{name:<26}{cells}")
    return "\n".join(lines)


ALBEDO_VIEWS = ((0, 0.7), (30, 0.7), (50, 0.7), (65, 0.7), (75, 0.7), (82, 0.7))
ALBEDO_WEIGHTS = {"Eq. 4.25": "4.25", "Eq. 4.24": "4.24", "A x mean, w = f cos": "fcos",
                  "A x mean, w = v": "v", "A x mean, w = p cos": "pcos"}


def albedo_estimate(wo, env, mx, my, r0, alpha, pattern, n, weights, kind="reflect"):
    """`estimate`, or the albedo-normalised mean with weights "fcos", "v" or "pcos"."""
    if weights in ("4.25", "4.24"):
        return estimate(wo, env, mx, my, r0, alpha, pattern, n, weights, kind)
    xi = P.pattern_xi(pattern, n)
    wi, f, p, c = P.pattern_samples(wo, xi, mx, my, r0, alpha, kind)
    lam_f = 12.0 / np.minimum(P.lobe_ellipse_area(wo, mx, my, kind) / n, OMEGA_MAX)
    L = radiance(wi / np.linalg.norm(wi, axis=-1, keepdims=True), env, lam_f)
    keep = (f > 0) & (p > 0) & (c > 0)
    w = np.where(keep, {"fcos": f * c, "v": f * c / np.where(keep, p, 1.0), "pcos": p * c}[weights], 0.0)
    albedo = float(bsdf.lobe_albedo(wo, mx, my, r0, alpha, kind))
    return albedo * float(np.sum(w * L)) / max(float(np.sum(w)), 1e-300)


def measure_albedo(seed: int, envs: int, log=print) -> str:
    """The table of `albedo`: error percentiles of each estimator over lobes x views x environments."""
    from glint.bake.material_mapping import GltfPbr, map_pbr

    lobes = []
    for metallic, base, r in ((1.0, 1.0, 0.3), (1.0, 1.0, 0.5), (0.0, 0.5, 0.25), (0.0, 0.5, 0.4)):
        (lobe,) = map_pbr(GltfPbr(base_color=(base,) * 3, metallic=metallic, roughness=r))[1]
        lobes.append((lobe.mx, lobe.my, lobe.r0, lobe.alpha, "ring"))
    lobes += [(0.1, 0.1, 0.5, 0.0, "ring"), (0.02, 0.2, 0.5, 0.5, "line_y")]
    rng = np.random.default_rng(seed)
    environments = [environment(rng) for _ in range(envs)]
    errors = {name: [] for name in ALBEDO_WEIGHTS}
    for mx, my, r0, alpha, pattern in lobes:
        n = P.samples_for_lobe(mx, my, False)
        for theta, phi in ALBEDO_VIEWS:
            wo = sph(np.radians(theta), phi)
            refs = np.array([reference(wo, e, mx, my, r0, alpha) for e in environments])
            for name, weights in ALBEDO_WEIGHTS.items():
                est = np.array([albedo_estimate(wo, e, mx, my, r0, alpha, pattern, n, weights) for e in environments])
                errors[name].append(np.abs(est - refs) / refs)
        log(f"  lobe m {mx:.3g} x {my:.3g}, alpha {alpha:.2f}: done")
    lines = ["| estimator | median | 75th | 90th |", "|---|---|---|---|"]
    for name, e in errors.items():
        e = np.concatenate(e) * 100
        lines.append(f"| {name} | {np.median(e):.1f} % | {np.percentile(e, 75):.1f} % | {np.percentile(e, 90):.1f} % |")
    return "\n".join(lines)


def cases(seed: int, envs: int):
    rng = np.random.default_rng(seed)
    environments = [environment(rng) for _ in range(envs)]
    return [(sph(np.radians(theta), phi), e) for theta, phi in VIEWS for e in environments]


# -- the two measurements --------------------------------------------------------------------------
def measure_samples(pattern: str, ms, seed: int, envs: int, r0: float, weights: str, log=print):
    """(est (len(ms), cases, len(NS)), ref (len(ms), cases)) for the ring (isotropic) or the line
    (m_y = 10 m_x)."""
    kind, ratio = PATTERN[pattern]
    todo = cases(seed, envs)
    est = np.zeros((len(ms), len(todo), len(NS)))
    ref = np.zeros((len(ms), len(todo)))
    for i, m in enumerate(ms):
        started = time.perf_counter()
        mx, my = m / ratio, m
        for k, (wo, env) in enumerate(todo):
            ref[i, k] = reference(wo, env, mx, my, r0, 0.0)
            est[i, k] = [estimate(wo, env, mx, my, r0, 0.0, kind, n, weights) for n in NS]
        log(f"  {pattern} m = {m:g}: {len(todo)} cases in {time.perf_counter() - started:.1f} s")
    return est, ref


def _pct(x: float) -> str:
    return f"{x:.1f}" if x < 10 else f"{x:.0f}"


def samples_table(pattern: str, ms, est, ref) -> str:
    rel = 100 * np.abs(est - ref[..., None]) / ref[..., None]
    p75, p90 = np.percentile(rel, 75, axis=1), np.percentile(rel, 90, axis=1)
    cols = [NS.index(n) for n in SHOWN]
    lines = ["    75th / 90th percentile error (%)   " + "".join(f"n = {n:<6}" if j == 0 else f"{n:<10}"
                                                           for j, n in enumerate(SHOWN)) + "first n within"]
    for i, m in enumerate(ms):
        cells = "".join(f"{_pct(p75[i, j]) + '/' + _pct(p90[i, j]):<10}" for j in cols)
        ok = [n for j, n in enumerate(NS) if p75[i, j] <= RULE[0] and p90[i, j] <= RULE[1]]
        rule = f"n = {ok[0]}" if ok else "-"
        head = pattern if i == 0 else ""
        lines.append(f"    {head:<6}m = {m:<25g}{cells}{rule}")
    return "\n".join(lines)


def measure_threshold(seed: int, envs: int, r0: float, weights: str, log=print):
    """{(m_max, n): [(ratio, ring %, line %), ...]}: ring against line at the same n."""
    todo = cases(seed, envs)
    out = {}
    for m_max in (0.03, 0.1, 0.2):
        for ratio in (1.5, 2, 2.5, 3, 4):
            started = time.perf_counter()
            mx, my = m_max / ratio, m_max
            refs = np.array([reference(wo, env, mx, my, r0, 0.0) for wo, env in todo])
            for n in (7, 11):
                errs = {}
                for pattern in ("ring", "line_y"):
                    e = np.array([estimate(wo, env, mx, my, r0, 0.0, pattern, n, weights) for wo, env in todo])
                    errs[pattern] = 100 * np.sum(np.abs(e - refs)) / np.sum(refs)
                out.setdefault((m_max, n), []).append((ratio, errs["ring"], errs["line_y"]))
            log(f"  threshold m_max = {m_max:g}, ratio {ratio:g}: {time.perf_counter() - started:.1f} s")
    return out


def threshold_table(result) -> str:
    ratios = [r for r, _, _ in next(iter(result.values()))]
    lines = ["    m_y / m_x                      " + "".join(f"{r:<11g}" for r in ratios)]
    for (m_max, n), row in sorted(result.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        label = f"m_max = {m_max:g}, n = {n} ring/line"
        lines.append(f"    {label:<31}" + "".join(f"{f'{a:.1f}/{b:.1f}':<11}" for _, a, b in row))
    return "\n".join(lines)


# -- command line ----------------------------------------------------------------------------------
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", nargs="?", default="all", choices=("all", "samples", "threshold", "fis", "albedo"),
                        help="the sample-count tables (ring and line), the ring/line threshold table, all of "
                             "those, or patterns against filtered importance sampling (fis)")
    parser.add_argument("--pattern", choices=("ring", "line", "both"), default="both",
                        help="samples: which pattern (default both)")
    parser.add_argument("--ms", help="samples: roughness values m, comma-separated "
                                     f"(default ring {','.join(map(str, DEFAULT_MS['ring']))}; "
                                     f"line {','.join(map(str, DEFAULT_MS['line']))})")
    parser.add_argument("--seed", type=int, help="environment seed (default: samples and fis 11, threshold 21)")
    parser.add_argument("--envs", type=int, help="environments (default: samples 40, threshold 30, fis 20)")
    parser.add_argument("--r0", type=float, default=0.5, help="Fresnel r0 of the lobes (default 0.5)")
    parser.add_argument("--weights", choices=("4.25", "4.24", "4.23"), default="4.25",
                        help="the pattern estimator's weights (default Eq. 4.25)")
    parser.add_argument("--save", type=Path, metavar="FILE.npz", help="samples: keep the raw estimates")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    args = parser.parse_args(argv)
    log = (lambda *a: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))

    if args.what in ("all", "samples"):
        seed, envs = (11 if args.seed is None else args.seed), (40 if args.envs is None else args.envs)
        patterns = ("ring", "line") if args.pattern == "both" else (args.pattern,)
        print(f"Sample counts: {envs} environments (seed {seed}) x {len(VIEWS)} views = {envs * len(VIEWS)} "
              f"cases per lobe, r0 = {args.r0:g}, Eq. {args.weights}; ring: m_x = m_y = m, line: m_y = 10 m_x = m")
        print(f"first n within: the smallest n with 75th <= {RULE[0]:g}% and 90th <= {RULE[1]:g}% (of n = "
              f"{', '.join(map(str, NS))}); the rules of samples_for_lobe are read off these tables\n")
        saved = {}
        for pattern in patterns:
            ms = [float(x) for x in args.ms.split(",")] if args.ms else list(DEFAULT_MS[pattern])
            est, ref = measure_samples(pattern, ms, seed, envs, args.r0, args.weights, log)
            print(samples_table(pattern, ms, est, ref), flush=True)
            saved.update({f"{pattern}_est": est, f"{pattern}_ref": ref, f"{pattern}_ms": np.array(ms)})
        if args.save:  # np.savez's own naming: ".npz" appended when missing
            path = args.save if args.save.suffix == ".npz" else args.save.with_name(args.save.name + ".npz")
            with atomic_path(path) as tmp, open(tmp, "wb") as f:
                np.savez(f, ns=np.array(NS), **saved)
        print()
    if args.what in ("all", "threshold"):
        seed, envs = (21 if args.seed is None else args.seed), (30 if args.envs is None else args.envs)
        print(f"Threshold: ring against line at the same n (sum of errors over sum of references, %), "
              f"{envs} environments (seed {seed}) x {len(VIEWS)} views, r0 = {args.r0:g}, Eq. {args.weights}\n")
        print(threshold_table(measure_threshold(seed, envs, args.r0, args.weights, log)))
    if args.what == "albedo":
        seed, envs = (21 if args.seed is None else args.seed), (16 if args.envs is None else args.envs)
        print(f"The walkthrough's estimators against the lobe integral, {envs} environments (seed {seed}) x "
              f"{len(ALBEDO_VIEWS)} views (0-82 degrees) x 6 lobes\n")
        print(measure_albedo(seed, envs, log))
    if args.what == "fis":
        seed, envs = (11 if args.seed is None else args.seed), (20 if args.envs is None else args.envs)
        ms = [float(x) for x in args.ms.split(",")] if args.ms else [0.02, 0.05, 0.1]
        ns = (1, 3, 5, 7, 11, 19)
        print(f"Patterns (ring, Eq. 4.25) against filtered importance sampling and unfiltered QMC (isotropic "
              f"lobes m_x = m_y = m), {envs} environments (seed {seed}) x {len(VIEWS)} views, r0 = {args.r0:g}\n"
              f"fis-shader: R2 points 0 .. n-1 as shaders/specular.glsl; fis-centred: Hammersley "
              f"((i + 1/2)/n, radical inverse); qmc: unfiltered, mean error over 16 per-pixel rotations\n")
        print(fis_table(ms, ns, measure_fis(ms, ns, seed, envs, args.r0, log)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
