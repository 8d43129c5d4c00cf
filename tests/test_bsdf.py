"""The path tracer's BSDFs (kernels/shading/materials/) against independent checks: chi-square tests of
bsdf_sample's directions against bsdf_eval's density (what pbrt's and Mitsuba's BSDF test
suites do), sample weights against f |cos| / pdf, reciprocity, energy (albedo) bounds and
closed forms (Fresnel equations written here with complex numbers, Snell's law, Lambert),
and finite results at grazing angles and near-zero roughness. Random numbers come from fixed
seeds; tolerances are a few standard errors of each estimate."""

import math

import numpy as np
import pytest
from numba import njit
from scipy import stats

from raylume.kernels.shading.materials import (
    BY_NAME,
    MAT_COLOR,
    MAT_ETA,
    MAT_HAS_ETA,
    MAT_IOR,
    MAT_K,
    MAT_KIND,
    MAT_REFLECTIVE,
    MAT_ROUGHNESS,
    MAT_SPECULAR,
    MAT_TRANSPARENCY,
    MAT_WIDTH,
    bsdf_eval,
    bsdf_sample,
)
from raylume.kernels.shading.materials import coating as bsdf
from raylume.kernels.shading.materials.coating import coat_terms, fresnel_diffuse_reflectance
from raylume.kernels.shading.materials.conductor import fresnel_conductor

PHONG, DIFFUSE, CONDUCTOR, DIELECTRIC, PLASTIC = (
    BY_NAME[name].KIND for name in ("phong", "diffuse", "conductor", "dielectric", "plastic")
)

# The checks below share njit helpers (cached, but compiled on a fresh machine): one xdist worker
# runs them all, so that the two workers do not each compile them at the same time.
pytestmark = pytest.mark.xdist_group("bsdf")

GOLD_ETA = (0.143, 0.374, 1.442)  # gold at ~650, 550, 450 nm (Johnson and Christy)
GOLD_K = (3.983, 2.385, 1.603)
GREY = (0.8, 0.8, 0.8)
WHITE = (1.0, 1.0, 1.0)


def material(kind, color=GREY, roughness=0.0, ior=1.5, eta=None, k=None, specular=-1.0, reflective=0.0, transparency=0):
    """A one-row material table."""
    row = np.zeros((1, MAT_WIDTH))
    row[0, MAT_KIND] = kind
    row[0, MAT_COLOR : MAT_COLOR + 3] = color
    row[0, MAT_ROUGHNESS] = roughness
    row[0, MAT_IOR] = ior
    row[0, MAT_SPECULAR] = specular
    row[0, MAT_REFLECTIVE] = reflective
    row[0, MAT_TRANSPARENCY] = transparency
    if eta is not None:
        row[0, MAT_ETA : MAT_ETA + 3] = eta
        row[0, MAT_K : MAT_K + 3] = k
        row[0, MAT_HAS_ETA] = 1.0
    return row


def direction(theta_deg, phi_deg=0.0):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))


def unit(v):
    return tuple(float(x) for x in np.array(v) / np.linalg.norm(v))


def fresnel_complex(cos_i, n):
    """Unpolarised Fresnel reflectance from index 1 into complex index n (the textbook
    amplitudes with a complex cosine of refraction; an imaginary one under total internal
    reflection gives 1). Vectorised over cos_i."""
    cos_i = np.asarray(cos_i, dtype=float)
    n = complex(n)
    cos_t = np.sqrt(1.0 - (1.0 - cos_i**2) / (n * n) + 0j)
    r_s = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    r_p = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return 0.5 * (np.abs(r_s) ** 2 + np.abs(r_p) ** 2)


def fresnel_real(cos_i, eta_ratio):
    """Dielectric reflectance for light arriving from index n_i onto n_t, eta_ratio = n_i / n_t."""
    return fresnel_complex(cos_i, 1.0 / eta_ratio)


def hemispherical(eta_ratio):
    """2 int_0^1 R(mu) mu dmu of fresnel_real(mu, eta_ratio), by Gauss-Legendre on either side of
    the critical angle's cosine (total internal reflection below it: a kink)."""
    x, w = np.polynomial.legendre.leggauss(100)
    mu_c = math.sqrt(max(0.0, 1.0 - 1.0 / eta_ratio**2))
    total = 0.0
    for lo, hi in ((0.0, mu_c), (mu_c, 1.0)):
        mu = lo + (hi - lo) * 0.5 * (x + 1.0)
        total += (hi - lo) * 0.5 * np.sum(w * 2.0 * mu * fresnel_real(mu, eta_ratio))
    return total


# Python calls go through these (cached) so that a warm run compiles nothing.


@njit(cache=True)
def evaluate(mat, color, wo, wi):
    return bsdf_eval(mat, 0, color, wo, wi)


@njit(cache=True)
def sample(mat, color, wo, u0, u1, u2):
    return bsdf_sample(mat, 0, color, wo, u0, u1, u2)


@njit(cache=True)
def conductor_fresnel(cos_i, eta, k):
    return fresnel_conductor(cos_i, eta, k)


@njit(cache=True)
def diffuse_fresnel(eta):
    return fresnel_diffuse_reflectance(eta)


@njit(cache=True)
def coat(alpha, eta, mu):
    return coat_terms(alpha, eta, mu)


# --- Monte Carlo loops (compiled) -------------------------------------------------------------


@njit(cache=True)
def _radiance_undo(mat, wo, wi):
    """(n_wi / n_wo)^2 for a refraction (undoes the radiance scaling), 1 for a reflection."""
    if wo[2] * wi[2] >= 0.0:
        return 1.0
    ior = mat[0, MAT_IOR]
    return ior * ior if wo[2] > 0.0 else 1.0 / (ior * ior)


@njit(cache=True)
def _sample_stats(mat, color, wo, n, seed, ntheta, nphi, theta_hi):
    """Draws n samples. Returns the histogram of non-delta directions over ntheta x nphi cells
    uniform in (theta, phi) on [0, theta_hi] x [0, 2 pi); the number of other samples (delta or failed);
    the largest relative mismatch of a non-delta sample's pdf and weight against bsdf_eval's
    pdf and f |cos| / pdf; the sum and sum of squares of the weights per channel (the radiance
    factor of refractions undone); and whether every output was finite and sane."""
    np.random.seed(seed)
    hist = np.zeros((ntheta, nphi))
    other = 0
    worst = 0.0
    sums = np.zeros(3)
    squares = np.zeros(3)
    sane = True
    for _ in range(n):
        wi, w, pdf, delta = bsdf_sample(mat, 0, color, wo, np.random.random(), np.random.random(), np.random.random())
        for c in range(3):
            if not (np.isfinite(w[c]) and w[c] >= 0.0):
                sane = False
        if not (np.isfinite(pdf) and pdf >= 0.0):
            sane = False
        if pdf > 0.0 and abs(wi[0] ** 2 + wi[1] ** 2 + wi[2] ** 2 - 1.0) > 1e-9:
            sane = False
        undo = _radiance_undo(mat, wo, wi) if pdf > 0.0 else 1.0
        for c in range(3):
            sums[c] += w[c] * undo
            squares[c] += (w[c] * undo) ** 2
        if delta or pdf == 0.0:
            other += 1
            continue
        f, pdf_e = bsdf_eval(mat, 0, color, wo, wi)
        worst = max(worst, abs(pdf - pdf_e) / pdf_e)
        for c in range(3):
            expected = f[c] * abs(wi[2]) / pdf_e
            worst = max(worst, abs(w[c] - expected) / max(expected, 1e-12))
        theta = math.acos(min(max(wi[2], -1.0), 1.0))
        phi = math.atan2(wi[1], wi[0])
        if phi < 0.0:
            phi += 2.0 * math.pi
        it = int(theta / theta_hi * ntheta)
        ip = min(int(phi / (2.0 * math.pi) * nphi), nphi - 1)
        if it >= ntheta:
            sane = False  # beyond the range the kind should sample
        else:
            hist[it, ip] += 1.0
    return hist, other, worst, sums, squares, sane


@njit(cache=True)
def _pdf_cells(mat, color, wo, ntheta, nphi, theta_hi, sub):
    """The integral of bsdf_eval's pdf over each cell of _sample_stats' grid (midpoint rule on
    sub x sub points per cell; d omega = sin theta dtheta dphi)."""
    cells = np.zeros((ntheta, nphi))
    dtheta = theta_hi / ntheta
    dphi = 2.0 * math.pi / nphi
    for it in range(ntheta):
        for ip in range(nphi):
            acc = 0.0
            for a in range(sub):
                theta = (it + (a + 0.5) / sub) * dtheta
                z, r = math.cos(theta), math.sin(theta)
                for b in range(sub):
                    phi = (ip + (b + 0.5) / sub) * dphi
                    acc += bsdf_eval(mat, 0, color, wo, (r * math.cos(phi), r * math.sin(phi), z))[1] * r
            cells[it, ip] = acc * dtheta * dphi / (sub * sub)
    return cells


@njit(cache=True)
def _uniform_albedo(mat, color, wo, n, seed, z_lo):
    """Integral of f |cos wi| over z in [z_lo, 1] with uniform directions (not using the sampler):
    per-channel mean and standard error (radiance factor of refractions undone)."""
    np.random.seed(seed)
    area = 2.0 * math.pi * (1.0 - z_lo)
    sums = np.zeros(3)
    squares = np.zeros(3)
    for _ in range(n):
        z = z_lo + (1.0 - z_lo) * np.random.random()
        phi = 2.0 * math.pi * np.random.random()
        r = math.sqrt(max(0.0, 1.0 - z * z))
        wi = (r * math.cos(phi), r * math.sin(phi), z)
        f = bsdf_eval(mat, 0, color, wo, wi)[0]
        undo = _radiance_undo(mat, wo, wi)
        for c in range(3):
            v = f[c] * abs(z) * area * undo
            sums[c] += v
            squares[c] += v * v
    mean = sums / n
    return mean, np.sqrt(np.maximum(squares / n - mean * mean, 0.0) / n)


def sampled_albedo(mat, color, wo, n=20000, seed=1):
    """Per-channel mean weight of bsdf_sample (the albedo estimate) and its standard error."""
    _, _, _, sums, squares, sane = _sample_stats(mat, color, wo, n, seed, 1, 1, 4.0)
    assert sane
    mean = sums / n
    return mean, np.sqrt(np.maximum(squares / n - mean**2, 0.0) / n)


def chi2_pvalue(observed, expected):
    """Pearson's test, cells expecting fewer than 5 samples pooled into one (as pbrt does)."""
    obs, exp = observed.ravel(), expected.ravel()
    small = exp < 5.0
    o = np.append(obs[~small], obs[small].sum())
    e = np.append(exp[~small], exp[small].sum())
    if e[-1] <= 0.0:
        if o[-1] > 0:
            return 0.0  # samples where the density is 0
        o, e = o[:-1], e[:-1]
    statistic = ((o - e) ** 2 / e).sum()
    return stats.chi2.sf(statistic, len(o) - 1)


# --- Sampling matches the density -------------------------------------------------------------

CHI2_CASES = {
    "diffuse": (material(DIFFUSE), False),
    "conductor-0.2": (material(CONDUCTOR, roughness=0.2, eta=GOLD_ETA, k=GOLD_K), False),
    "conductor-0.6": (material(CONDUCTOR, roughness=0.6), False),
    "dielectric-0.3": (material(DIELECTRIC, roughness=0.3, ior=1.5), True),
    "dielectric-0.7": (material(DIELECTRIC, roughness=0.7, ior=1.33, color=(0.9, 0.7, 0.5)), True),
    "plastic-0.3": (material(PLASTIC, roughness=0.3, color=(0.5, 0.3, 0.2)), False),
    "plastic-smooth": (material(PLASTIC, color=(0.5, 0.3, 0.2)), False),
    "phong": (material(PHONG, specular=20.0, reflective=0.2), False),
    "phong-glass": (material(PHONG, specular=20.0, reflective=0.1, transparency=0.4, ior=1.5), True),
}


@pytest.mark.parametrize(
    "case, theta",
    [(c, t) for c, (_, full) in CHI2_CASES.items() for t in (10.0, 50.0, 80.0) + ((130.0,) if full else ())],
)
def test_sampled_directions_follow_the_pdf(case, theta):
    """Chi-square of bsdf_sample's directions against bsdf_eval's pdf integrated over a grid of
    cells (the full sphere for the kinds that transmit, which are also lit from inside), delta
    and failed samples in one more cell; non-delta weights equal f |cos wi| / pdf with
    bsdf_eval's f and pdf."""
    mat, full_sphere = CHI2_CASES[case]
    color = tuple(mat[0, MAT_COLOR : MAT_COLOR + 3])
    wo = direction(theta, 30.0)
    n, ntheta, nphi = 100_000, (40 if full_sphere else 20), 24
    theta_hi = math.pi if full_sphere else 0.5 * math.pi
    hist, other, worst, _, _, sane = _sample_stats(mat, color, wo, n, 7, ntheta, nphi, theta_hi)
    assert sane
    assert worst < 1e-9, "a sample's weight or pdf differs from bsdf_eval's"
    expected = n * _pdf_cells(mat, color, wo, ntheta, nphi, theta_hi, 12)
    observed = np.append(hist.ravel(), other)
    expected = np.append(expected.ravel(), max(n - expected.sum(), 0.0))
    assert chi2_pvalue(observed, expected) > 1e-3


def test_chi_square_detects_a_wrong_density():
    """The test above has power: a sampler's histogram against a slightly wrong density fails."""
    mat = material(CONDUCTOR, roughness=0.3)
    color, wo = WHITE, direction(40.0)
    hist, other, _, _, _, _ = _sample_stats(mat, color, wo, 100_000, 7, 20, 24, 0.5 * math.pi)
    wrong = 100_000 * _pdf_cells(material(CONDUCTOR, roughness=0.33), color, wo, 20, 24, 0.5 * math.pi, 12)
    assert chi2_pvalue(np.append(hist.ravel(), other), np.append(wrong.ravel(), 100_000 - wrong.sum())) < 1e-6


# --- Reciprocity and energy -------------------------------------------------------------------


@pytest.mark.parametrize(
    "mat",
    [
        material(DIFFUSE),
        material(CONDUCTOR, roughness=0.25, eta=GOLD_ETA, k=GOLD_K),
        material(PLASTIC),
        material(PLASTIC, roughness=0.4, ior=1.7),
        material(PHONG, specular=30.0, reflective=0.3),
    ],
    ids=["diffuse", "conductor", "plastic", "rough-plastic", "phong"],
)
def test_reflection_bsdfs_are_reciprocal(mat):
    rng = np.random.default_rng(3)
    color = (0.7, 0.5, 0.3)
    for _ in range(200):
        a, b = rng.normal(size=(2, 3))
        a[2], b[2] = abs(a[2]), abs(b[2])
        wo, wi = tuple(a / np.linalg.norm(a)), tuple(b / np.linalg.norm(b))
        f_ab = np.array(evaluate(mat, color, wo, wi)[0])
        f_ba = np.array(evaluate(mat, color, wi, wo)[0])
        assert f_ab.max() > 0.0
        np.testing.assert_allclose(f_ab, f_ba, rtol=1e-9)


ALBEDO_CASES = {
    "diffuse": material(DIFFUSE, color=WHITE),
    "mirror": material(CONDUCTOR, color=WHITE),
    "gold": material(CONDUCTOR, color=WHITE, eta=GOLD_ETA, k=GOLD_K),
    **{f"conductor-{a}": material(CONDUCTOR, color=WHITE, roughness=a) for a in (1e-3, 0.05, 0.3, 1.0)},
    "gold-0.3": material(CONDUCTOR, color=WHITE, roughness=0.3, eta=GOLD_ETA, k=GOLD_K),
    **{f"dielectric-{a}": material(DIELECTRIC, color=WHITE, roughness=a) for a in (0.0, 1e-3, 0.05, 0.3, 1.0)},
    "dielectric-2.4-0.3": material(DIELECTRIC, color=WHITE, roughness=0.3, ior=2.4),
    **{f"plastic-{a}": material(PLASTIC, color=WHITE, roughness=a) for a in (0.0, 1e-3, 0.05, 0.3, 1.0)},
    "plastic-2.5-0.5": material(PLASTIC, color=WHITE, roughness=0.5, ior=2.5),
    "phong-matte": material(PHONG, color=WHITE),
    "phong-shiny": material(PHONG, color=WHITE, specular=50.0, reflective=0.3),
    "phong-glass": material(PHONG, color=WHITE, specular=10.0, reflective=0.2, transparency=0.5),
}


@pytest.mark.parametrize("case", ALBEDO_CASES)
def test_albedo_at_most_one(case):
    """The Monte Carlo albedo (integral of f |cos wi|, the radiance factor of refractions undone)
    of a white material is at most 1 + 4 standard errors, for wo from normal to grazing (and
    from inside for the kinds that transmit)."""
    mat = ALBEDO_CASES[case]
    thetas = [0.0, 30.0, 60.0, 80.0, 89.9]
    if mat[0, MAT_KIND] == DIELECTRIC or mat[0, MAT_TRANSPARENCY] > 0.0:
        thetas += [180.0 - t for t in thetas]
    for theta in thetas:
        mean, se = sampled_albedo(mat, WHITE, direction(theta))
        assert np.all(mean <= 1.0 + 4.0 * se + 1e-12), (theta, mean, se)


@pytest.mark.parametrize(
    "mat",
    [
        material(DIFFUSE, color=(0.9, 0.5, 0.2)),
        material(CONDUCTOR, roughness=0.4, color=(0.9, 0.5, 0.2), eta=GOLD_ETA, k=GOLD_K),
        material(DIELECTRIC, roughness=0.4, color=(0.9, 0.5, 0.2)),
        material(PLASTIC, roughness=0.2, color=(0.9, 0.5, 0.2)),
        material(PHONG, specular=8.0, color=(0.9, 0.5, 0.2)),
    ],
    ids=["diffuse", "conductor", "dielectric", "plastic", "phong"],
)
def test_sampled_albedo_matches_uniform_integration(mat):
    """Importance sampling and plain uniform integration of bsdf_eval give the same albedo."""
    color = tuple(mat[0, MAT_COLOR : MAT_COLOR + 3])
    for theta in (20.0, 70.0, 160.0) if mat[0, MAT_KIND] == DIELECTRIC else (20.0, 70.0):
        a, sa = sampled_albedo(mat, color, direction(theta), n=50_000)
        b, sb = _uniform_albedo(mat, color, direction(theta), 200_000, 5, -1.0)
        assert np.all(np.abs(a - b) <= 5.0 * np.hypot(sa, sb)), (theta, a, b)


def test_diffuse_albedo_is_its_color():
    color = (0.9, 0.5, 0.2)
    mat = material(DIFFUSE, color=color)
    for theta in (0.0, 45.0, 85.0):
        mean, se = _uniform_albedo(mat, color, direction(theta), 200_000, 2, 0.0)
        assert np.all(np.abs(mean - color) <= 4.0 * se)
        wi, w, pdf, delta = sample(mat, color, direction(theta), 0.5, 0.3, 0.8)
        np.testing.assert_allclose(w, color, rtol=1e-12)
        assert pdf == pytest.approx(wi[2] / math.pi) and not delta


def test_phong_without_highlight_mirror_or_glass_is_lambert():
    color = (0.9, 0.5, 0.2)
    mat = material(PHONG, color=color)
    f, pdf = evaluate(mat, color, direction(30.0), direction(50.0, 120.0))
    np.testing.assert_allclose(f, np.array(color) / math.pi, rtol=1e-12)
    assert pdf == pytest.approx(math.cos(math.radians(50.0)) / math.pi)


def test_rough_conductor_loses_some_energy():
    """Single-scattering GGX (no multiple bounces between microfacets) reflects less than a
    white mirror, but not much less at moderate roughness near normal incidence."""
    mat = material(CONDUCTOR, color=WHITE, roughness=0.3)
    mean, se = sampled_albedo(mat, WHITE, direction(10.0), n=200_000)
    assert np.all(mean < 1.0 - 4.0 * se)
    assert np.all(mean > 0.8)
    mean, _ = sampled_albedo(material(CONDUCTOR, color=WHITE, roughness=1.0), WHITE, direction(10.0), n=200_000)
    assert np.all(mean < 0.9)  # rougher loses more


def test_smooth_white_plastic_conserves_energy():
    """Mitsuba's smooth plastic with a white base: coating reflection F plus the diffuse part
    (1 - F) T_hemi / (eta^2 (1 - Fdr_int)), which is 1 - F because T_hemi = eta^2 (1 - Fdr_int)
    for a smooth interface: the albedo is 1 up to the accuracy of the Fdr fit."""
    mat = material(PLASTIC, color=WHITE, ior=1.5)
    for theta in (0.0, 60.0, 85.0):
        mean, se = sampled_albedo(mat, WHITE, direction(theta), n=100_000)
        assert np.all(np.abs(mean - 1.0) <= 4.0 * se + 0.005), (theta, mean)


# --- Against Mitsuba 3 ------------------------------------------------------------------------

# (material, wo, wi, f |cos wi|, pdf) from Mitsuba 3.9.1's scalar_rgb variant, whose BSDF.eval
# includes the cosine and names our wo si.wi: b = mi.load_dict(d); si.wi = wo; si.sh_frame =
# Frame3f((0, 0, 1)); b.eval(BSDFContext(), si, wi), b.pdf(BSDFContext(), si, wi), with d =
# {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "eta": GOLD_ETA, "k": GOLD_K,
# "specular_reflectance": C}, {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3,
# "int_ior": 1.5, "ext_ior": 1.0, "specular_transmittance": C}, {"type": "plastic", "int_ior":
# 1.5, "ext_ior": 1.0, "diffuse_reflectance": C}, and roughplastic ("distribution": "ggx") with
# alpha 0.3, int_ior 1.5 and alpha 0.6, int_ior 1.9; C = (0.7, 0.5, 0.3).
MITSUBA = [
    ("roughconductor", (0.0, 0.6, 0.8), (0.48, -0.6, 0.64), (0.176897, 0.104875, 0.0260259), 0.269892),
    ("roughconductor", (0.8, 0.0, 0.6), (-0.6, 0.0, 0.8), (0.655209, 0.388559, 0.0977008), 0.981778),
    ("roughdielectric", (0.0, 0.6, 0.8), (0.48, -0.6, 0.64), (0.0120841, 0.0120841, 0.0120841), 0.0124641),
    ("roughdielectric", (0.8, 0.0, 0.6), (-0.6, 0.0, 0.8), (0.0487155, 0.0487155, 0.0487155), 0.0493245),
    ("roughdielectric", (0.0, 0.6, 0.8), (0.359984, 0.0, -0.932958), (0.00229816, 0.00164154, 0.000984924), 0.00741159),
    ("roughdielectric", (0.28, 0.0, -0.96), (0.6, 0.0, 0.8), (0.0, 0.0, 0.0), 0.0),
    ("roughdielectric", (0.28, 0.0, -0.96), (-0.500011, 0.0, -0.866019), (0.0303145, 0.0303145, 0.0303145), 0.0305402),
    ("plastic", (0.0, 0.6, 0.8), (0.48, -0.6, 0.64), (0.141569, 0.10112, 0.0606723), 0.186586),
    ("plastic", (0.8, 0.0, 0.6), (-0.6, 0.0, 0.8), (0.175746, 0.125533, 0.0753196), 0.223778),
    ("roughplastic", (0.0, 0.6, 0.8), (0.48, -0.6, 0.64), (0.105395, 0.0787345, 0.0520744), 0.211299),
    ("roughplastic", (0.8, 0.0, 0.6), (-0.6, 0.0, 0.8), (0.164396, 0.131345, 0.0982931), 0.375116),
    ("roughplastic-1.9", (0.0, 0.6, 0.8), (0.48, -0.6, 0.64), (0.0604085, 0.0481877, 0.035967), 0.199924),
    ("roughplastic-1.9", (0.8, 0.0, 0.6), (-0.6, 0.0, 0.8), (0.0838288, 0.0687567, 0.0536845), 0.270682),
]
MITSUBA_COLOR = (0.7, 0.5, 0.3)
MITSUBA_MATERIALS = {
    "roughconductor": material(CONDUCTOR, MITSUBA_COLOR, roughness=0.3, eta=GOLD_ETA, k=GOLD_K),
    "roughdielectric": material(DIELECTRIC, MITSUBA_COLOR, roughness=0.3, ior=1.5),
    "plastic": material(PLASTIC, MITSUBA_COLOR, ior=1.5),
    "roughplastic": material(PLASTIC, MITSUBA_COLOR, roughness=0.3, ior=1.5),
    "roughplastic-1.9": material(PLASTIC, MITSUBA_COLOR, roughness=0.6, ior=1.9),
}


@pytest.mark.parametrize("case", MITSUBA, ids=[f"{c[0]}-{i}" for i, c in enumerate(MITSUBA)])
def test_matches_mitsuba(case):
    """Mitsuba's values to its single precision; rough plastic to 1 % (its tables: Mitsuba's per
    material, raylume's interpolated over alpha and eta)."""
    name, wo, wi, f_cos, pdf = case
    wo, wi = unit(wo), unit(wi)
    f, p = evaluate(MITSUBA_MATERIALS[name], MITSUBA_COLOR, wo, wi)
    rel = 0.01 if name.startswith("rough") and "plastic" in name else 2e-5
    np.testing.assert_allclose(np.array(f) * abs(wi[2]), f_cos, rtol=rel, atol=1e-7)
    assert p == pytest.approx(pdf, rel=rel, abs=1e-7)


# --- Closed forms -----------------------------------------------------------------------------


def test_conductor_fresnel_matches_the_complex_fresnel_equations():
    for n, k in zip(GOLD_ETA + (1.0972,), GOLD_K + (6.7942,)):  # gold, aluminium at 550 nm
        normal = ((n - 1.0) ** 2 + k**2) / ((n + 1.0) ** 2 + k**2)
        assert conductor_fresnel(1.0, n, k) == pytest.approx(normal, rel=1e-12)
        for cos_i in (0.0, 1e-6, 0.1, 0.5, 0.9):
            expected = fresnel_complex(cos_i, n + 1j * k)
            assert conductor_fresnel(cos_i, n, k) == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # a dielectric is a conductor with k = 0
    assert conductor_fresnel(0.6, 1.5, 0.0) == pytest.approx(fresnel_complex(0.6, 1.5), rel=1e-12)


def test_smooth_conductor_is_a_mirror_times_color_or_fresnel():
    color = (0.9, 0.6, 0.3)
    wo = direction(35.0, 70.0)
    wi, w, pdf, delta = sample(material(CONDUCTOR, color=color), color, wo, 0.3, 0.6, 0.9)
    assert delta and pdf == 1.0 and w == color
    np.testing.assert_allclose(wi, (-wo[0], -wo[1], wo[2]), atol=1e-15)
    gold = material(CONDUCTOR, color=color, eta=GOLD_ETA, k=GOLD_K)
    wi, w, pdf, delta = sample(gold, color, wo, 0.3, 0.6, 0.9)
    expected = [c * fresnel_complex(wo[2], n + 1j * k) for c, n, k in zip(color, GOLD_ETA, GOLD_K)]
    np.testing.assert_allclose(w, expected, rtol=1e-9)
    assert evaluate(material(CONDUCTOR, color=color), color, wo, wi) == ((0.0, 0.0, 0.0), 0.0)


@pytest.mark.parametrize("ior", [1.5, 1.0, 0.7])
@pytest.mark.parametrize("theta", [0.0, 25.0, 55.0, 80.0, 89.99, 100.0, 135.0, 160.0, 180.0])
def test_smooth_dielectric_fresnel_snell_and_energy(ior, theta):
    """Reflection with probability and reflectance F (the Fresnel equations), refraction by
    Snell's law carrying (1 - F) tint (n_wo / n_wi)^2: R + T (n_wi / n_wo)^2 == 1."""
    tint = (0.9, 0.8, 0.7)
    mat = material(DIELECTRIC, color=tint, ior=ior)
    wo = direction(theta, 40.0)
    n_wo, n_other = (1.0, ior) if wo[2] > 0 else (ior, 1.0)
    f = fresnel_real(abs(wo[2]), n_wo / n_other)
    if f > 1e-12:  # (index matched: no reflection)
        wi, w, pdf, delta = sample(mat, tint, wo, 0.0, 0.5, 0.5)
        assert delta and w == (1.0, 1.0, 1.0)
        assert pdf == pytest.approx(f, rel=1e-9)
        np.testing.assert_allclose(wi, (-wo[0], -wo[1], wo[2]), atol=1e-15)
    if f > 1.0 - 1e-12:  # total internal reflection: always
        assert sample(mat, tint, wo, 1.0 - 2.0**-53, 0.5, 0.5)[2] == 1.0
        return
    wt, w, pdf_t, delta = sample(mat, tint, wo, 1.0 - 2.0**-53, 0.5, 0.5)
    assert delta and pdf_t == pytest.approx(1.0 - f, rel=1e-9)
    assert wt[2] * wo[2] < 0.0
    sin_o, sin_t = math.hypot(wo[0], wo[1]), math.hypot(wt[0], wt[1])
    assert n_wo * sin_o == pytest.approx(n_other * sin_t, abs=1e-12)  # Snell
    assert wt[0] * wo[0] <= 0.0 and wt[1] * wo[1] <= 0.0  # on the far side of the normal
    np.testing.assert_allclose(np.array(w) / tint, (n_wo / n_other) ** 2, rtol=1e-12)
    r = f
    t = w[0] / tint[0] * pdf_t
    assert r + t * (n_other / n_wo) ** 2 == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("transparency", [0.0, 0.3])
def test_phong_albedo_at_normal_incidence(transparency):
    """At normal incidence the normalized Phong lobe reflects all it gets, so the mapped
    material's albedo is exactly kl color + (1 - T) r + T (the glass's refraction counted
    without the radiance factor)."""
    color, t, r = (0.9, 0.5, 0.2), transparency, 0.2
    mat = material(PHONG, color=color, specular=20.0, reflective=r, transparency=t)
    mean, se = sampled_albedo(mat, color, (0.0, 0.0, 1.0), n=200_000)
    expected = (1.0 - t) * (1.0 - r) * np.array(color) + (1.0 - t) * r + t
    assert np.all(np.abs(mean - expected) <= 4.0 * se + 1e-12), (mean, expected)


def smith_g1_tan(v, alpha):
    """Smith's GGX masking in its textbook form, 2 / (1 + sqrt(1 + alpha^2 tan^2 theta))."""
    tan2 = (v[0] ** 2 + v[1] ** 2) / v[2] ** 2
    return 2.0 / (1.0 + math.sqrt(1.0 + alpha**2 * tan2))


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_microfacet_weights_are_fresnel_times_masking(alpha):
    """With visible normals sampled, f |cos wi| / pdf reduces to F G1(wi) (Heitz 2018), times
    the tint and the radiance factor (n_wo / n_wi)^2 for a refraction: an identity that checks
    bsdf_eval's f against its pdf (which the chi-square tests check against the sampler)."""
    rng = np.random.default_rng(4)
    color = (0.9, 0.6, 0.3)
    conductor = material(CONDUCTOR, roughness=alpha, color=color)
    glass = material(DIELECTRIC, roughness=alpha, color=color, ior=1.5)
    for _ in range(300):
        theta = rng.uniform(0.0, 89.0)
        outside = direction(theta, rng.uniform(0.0, 360.0))
        wi, w, pdf, delta = sample(conductor, color, outside, *rng.random(3))
        if pdf > 0.0:
            np.testing.assert_allclose(w, np.array(color) * smith_g1_tan(wi, alpha), rtol=1e-9)
        for wo in (outside, tuple(-np.array(outside))):  # the glass from outside and from inside
            u = rng.random(3)
            wi, w, pdf, delta = sample(glass, color, wo, *u)
            if pdf == 0.0:
                continue
            refracted = wi[2] * wo[2] < 0.0
            n_wo, n_wi = (1.0, 1.5) if wo[2] > 0.0 else (1.5, 1.0)
            expected = smith_g1_tan(wi, alpha) * ((n_wo / n_wi) ** 2 * np.array(color) if refracted else 1.0)
            np.testing.assert_allclose(w, np.broadcast_to(expected, 3), rtol=1e-8)


def test_phong_mirror_and_glass_lobes():
    # all mirror
    mat = material(PHONG, reflective=1.0)
    wi, w, pdf, delta = sample(mat, GREY, direction(40.0), 0.7, 0.1, 0.2)
    assert delta and pdf == 1.0 and w == pytest.approx((1.0, 1.0, 1.0))
    # all glass: the smooth dielectric with a white tint, whatever the colour
    mat = material(PHONG, transparency=1.0, color=(0.2, 0.4, 0.6), ior=1.5)
    f = fresnel_real(math.cos(math.radians(40.0)), 1.0 / 1.5)
    assert sample(mat, (0.2, 0.4, 0.6), direction(40.0), 0.0, 0.1, 0.2)[2] == pytest.approx(f)
    wi, w, pdf, delta = sample(mat, (0.2, 0.4, 0.6), direction(40.0), 0.99, 0.1, 0.2)
    assert delta and wi[2] < 0.0 and pdf == pytest.approx(1.0 - f)
    np.testing.assert_allclose(w, 1.0 / 1.5**2, rtol=1e-12)


def test_fresnel_diffuse_reflectance_fits():
    """Mitsuba's fits against the integral 2 int_0^1 F(mu) mu dmu, computed here."""
    for eta in (1.0 / 2.0, 1.0 / 1.5, 1.0 / 1.33, 1.33, 1.5, 2.0):
        exact = hemispherical(1.0 / eta)
        assert diffuse_fresnel(eta) == pytest.approx(exact, rel=0.01)


def test_coating_tables():
    """Rough plastic's tables against what they summarise: the rough dielectric BSDF's energy
    transmittance from outside and reflectance from inside (integrated on a fine grid), and at
    alpha -> 0 the Fresnel equations."""
    for eta in (1.2, 1.5, 2.2):
        for mu in (0.15, 0.5, 0.95):
            t, r_int = coat(1e-4, eta, mu)
            assert t == pytest.approx(1.0 - fresnel_real(mu, 1.0 / eta), abs=2e-3)
        # Mitsuba's internal reflectance, the mean of 2 mu R(mu) over 64 equally spaced mu: about
        # 63/64 of the integral + R(1) / 64, up to jumps as the critical angle crosses its points
        smooth = 63.0 / 64.0 * hemispherical(eta) + fresnel_real(1.0, eta) / 64.0
        assert r_int == pytest.approx(smooth, abs=1e-3)
        mu = np.maximum(np.arange(64) / 63.0, 1e-6)
        assert r_int == pytest.approx(np.mean(2.0 * mu * fresnel_real(mu, eta)), abs=0.01)
    for eta in (1.3, 2.0):
        glass = material(DIELECTRIC, color=WHITE, roughness=0.3, ior=eta)
        for theta in (10.0, 45.0, 70.0):
            transmitted = _hemisphere_albedo(glass, direction(theta), 300, -1.0)
            assert coat(0.3, eta, math.cos(math.radians(theta)))[0] == pytest.approx(transmitted, abs=3e-3)
        mus = np.maximum(np.arange(64) / 63.0, 1e-6)
        inside = [_hemisphere_albedo(glass, (-math.sqrt(1.0 - m * m), 0.0, -m), 80, -1.0) for m in mus]
        assert coat(0.3, eta, 0.5)[1] == pytest.approx(np.mean(2.0 * mus * inside), abs=3e-3)
    assert bsdf.COAT_TRANSMITTANCE.shape == (17, 17, 33) and np.all(np.isfinite(bsdf.COAT_INTERNAL))


@njit(cache=True)
def _hemisphere_albedo(mat, wo, n, side):
    """Integral of f |cos wi| (radiance factor undone) of a white material over the hemisphere
    of wi.z * side > 0: midpoint rule on n x 2n cells in (theta, phi), d omega = sin theta."""
    acc = 0.0
    for i in range(n):
        theta = (i + 0.5) / n * 0.5 * math.pi
        z, r = math.cos(theta) * side, math.sin(theta)
        for j in range(2 * n):
            phi = (j + 0.5) / n * math.pi
            wi = (r * math.cos(phi), r * math.sin(phi), z)
            acc += bsdf_eval(mat, 0, (1.0, 1.0, 1.0), wo, wi)[0][0] * abs(z) * r * _radiance_undo(mat, wo, wi)
    return acc * (0.5 * math.pi / n) * (math.pi / n)


# --- Robustness -------------------------------------------------------------------------------


@njit(cache=True)
def _all_finite(mat, color, wos, n, seed):
    """bsdf_sample and bsdf_eval for every wo in wos with n random (u0, u1, u2, wi) plus the
    extreme uniforms 0 and 1 - 2^-53: every number finite and not negative."""
    np.random.seed(seed)
    top = 1.0 - 2.0**-53
    for k in range(wos.shape[0]):
        wo = (wos[k, 0], wos[k, 1], wos[k, 2])
        for i in range(n + 8):
            if i < 8:
                u0, u1, u2 = (0.0 if i & 1 else top), (0.0 if i & 2 else top), (0.0 if i & 4 else top)
            else:
                u0, u1, u2 = np.random.random(), np.random.random(), np.random.random()
            wi, w, pdf, delta = bsdf_sample(mat, 0, color, wo, u0, u1, u2)
            values = (w[0], w[1], w[2], pdf, wi[0], wi[1], wi[2])
            for v in values[:4]:
                if not (np.isfinite(v) and v >= 0.0):
                    return False
            for v in values[4:]:
                if not np.isfinite(v):
                    return False
            j = (k + i) % wos.shape[0]  # evaluate against the other test directions too
            for v in ((wos[j, 0], wos[j, 1], wos[j, 2]), wi):
                f, pdf = bsdf_eval(mat, 0, color, wo, v)
                for v in (f[0], f[1], f[2], pdf):
                    if not (np.isfinite(v) and v >= 0.0):
                        return False
    return True


@pytest.mark.parametrize("roughness", [0.0, 1e-6, 1e-4, 1e-3, 0.5, 1.0])
@pytest.mark.parametrize("kind", ["diffuse", "conductor", "gold", "dielectric", "plastic", "phong"])
def test_no_nan_or_inf_at_grazing_angles_or_tiny_roughness(kind, roughness):
    mat = {
        "diffuse": material(DIFFUSE),
        "conductor": material(CONDUCTOR, roughness=roughness),
        "gold": material(CONDUCTOR, roughness=roughness, eta=GOLD_ETA, k=GOLD_K),
        "dielectric": material(DIELECTRIC, roughness=roughness, ior=1.5),
        "plastic": material(PLASTIC, roughness=roughness),
        "phong": material(PHONG, specular=1000.0, reflective=0.2, transparency=0.3),
    }[kind]
    s = math.sqrt(1.0 - 1e-16)
    wos = np.array(
        [
            (1.0, 0.0, 0.0),
            (s, 0.0, 1e-8),
            (s, 0.0, -1e-8),
            (0.0, s, 1e-8),
            (0.6, 0.8, 0.0),
            (0.0, 0.0, 1.0),
            (0.0, 0.0, -1.0),
            (0.0, 0.6, 0.8),
            (1e-9, 0.0, 1.0),
            (0.0, -0.6, -0.8),
        ]
    )
    assert _all_finite(mat, GREY, wos, 3000, 11)
