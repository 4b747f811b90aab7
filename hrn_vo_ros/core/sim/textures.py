"""Textures of the simulated planes: shape posters and a laid table."""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True, slots=True)
class Texture:
    """Irradiance on the plane: ``image[row, col]`` at (x0 + col*texel, y0 + row*texel)."""

    image: F32
    x0: float
    y0: float
    texel: float
    outside: float


def poly_mask(xx: F64, yy: F64, px: F64, py: F64) -> NDArray[np.bool_]:
    """Even-odd point-in-polygon test for grid points (vectorised over points)."""
    inside = np.zeros(xx.shape, dtype=bool)
    n = len(px)
    for i in range(n):
        x1, y1, x2, y2 = px[i], py[i], px[(i + 1) % n], py[(i + 1) % n]
        if y1 == y2:
            continue
        cond = (yy >= min(y1, y2)) & (yy < max(y1, y2))
        xc = x1 + (yy - y1) * (x2 - x1) / (y2 - y1)
        inside ^= cond & (xx < xc)
    return inside


def shape_outline(rng: np.random.Generator, kind: str, size: float) -> tuple[F64, F64] | None:
    """Vertices (unrotated, centred) of a polygon-like shape, or None for an ellipse."""
    if kind == 'ellipse':
        return None
    if kind == 'star':
        k = int(rng.integers(4, 8))
        ang = np.arange(2 * k) * np.pi / k
        rad = np.where(np.arange(2 * k) % 2 == 0, size, size * rng.uniform(0.35, 0.55))
    elif kind == 'rect':
        a = size * rng.uniform(0.5, 1.0)
        b = size * rng.uniform(0.2, 1.0)
        return np.array([-a, a, a, -a]), np.array([-b, -b, b, b])
    else:  # regular-ish polygon
        k = int(rng.integers(3, 7))
        ang = np.arange(k) * 2 * np.pi / k + rng.uniform(-0.15, 0.15, k)
        rad = size * rng.uniform(0.85, 1.0, k)
    return rad * np.cos(ang), rad * np.sin(ang)


def paint_shape(img: F64, rng: np.random.Generator, x0: float, y0: float, texel: float,
                cx: float, cy: float, kind: str, size: float, value: float,
                angle: float | None = None, aspect: float | None = None) -> None:
    """Paint one filled shape of ``value`` onto ``img`` (in place)."""
    half = size * 1.05
    c0 = max(int((cx - half - x0) / texel), 0)
    c1 = min(int((cx + half - x0) / texel) + 2, img.shape[1])
    r0 = max(int((cy - half - y0) / texel), 0)
    r1 = min(int((cy + half - y0) / texel) + 2, img.shape[0])
    if c1 <= c0 or r1 <= r0:
        return
    cols = x0 + np.arange(c0, c1) * texel - cx
    rows = y0 + np.arange(r0, r1) * texel - cy
    xx, yy = np.meshgrid(cols, rows)
    th = rng.uniform(0, 2 * np.pi) if angle is None else angle
    xr = np.cos(th) * xx + np.sin(th) * yy
    yr = -np.sin(th) * xx + np.cos(th) * yy
    if kind == 'ellipse':
        asp = rng.uniform(0.45, 1.0) if aspect is None else aspect
        mask = (xr / size) ** 2 + (yr / (size * asp)) ** 2 <= 1.0
    else:
        outline = shape_outline(rng, kind, size)
        assert outline is not None  # only ellipses have no outline
        mask = poly_mask(xr, yr, outline[0], outline[1])
    img[r0:r1, c0:c1][mask] = value


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> F64:
    """Zero-mean, unit-std smooth noise (correlation length ``sigma`` texels).

    Large ``sigma`` is made on a coarse grid and interpolated (a full-size Gaussian filter with
    a wide kernel would take seconds).
    """
    step = max(int(sigma / 3), 1)
    coarse_shape = (shape[0] // step + 3, shape[1] // step + 3)
    n = ndimage.gaussian_filter(rng.standard_normal(coarse_shape), sigma / step, mode='wrap')
    if step > 1:
        n = ndimage.zoom(n, step, order=1)[:shape[0], :shape[1]]
    n = n[:shape[0], :shape[1]]
    return np.asarray((n - n.mean()) / max(float(n.std()), 1e-12), dtype=np.float64)


def shapes_texture(rng: np.random.Generator, *, half_extent: float, texel: float,
                   density: float, blur_m: float, size: tuple[float, float] = (0.03, 0.08),
                   light: float = 0.8, shading: float = 0.06,
                   dark: tuple[float, float] = (0.06, 0.15),
                   grey: tuple[float, float] = (0.15, 0.45)) -> Texture:
    """A poster wall: dark polygons, stars, rectangles and ellipses on an uneven light ground.

    Args:
        rng: Random generator.
        half_extent: Half the side of the square textured area, metres.
        texel: Texture resolution, metres.
        density: Shapes per square metre.
        blur_m: Optical blur (Gaussian std) in metres on the plane.
        size: Range of the shape sizes (outer radius), metres.
        light: Mean irradiance of the background (1 = white).
        shading: Relative std of the smooth uneven lighting of the background.
        dark: Irradiance range of the dark shapes (half of them).
        grey: Irradiance range of the grey shapes (the other half).
    """
    n = int(round(2 * half_extent / texel))
    x0 = y0 = -half_extent
    ground = light * (1 + shading * smooth_noise(rng, (n, n), 0.25 / texel))
    img = ground.copy()
    # stratified placement (a jittered grid, like a poster layout): the number of shapes in
    # view, and so the event rate, varies little from seed to seed
    cell = 1.0 / math.sqrt(density)
    centres = np.arange(-half_extent + cell / 2, half_extent, cell)
    kinds = ('poly', 'poly', 'star', 'ellipse', 'ellipse', 'rect')
    for gx, gy in ((a, b) for a in centres for b in centres):
        kind = kinds[int(rng.integers(len(kinds)))]
        radius = float(rng.uniform(*size))
        cx, cy = np.array([gx, gy]) + rng.uniform(-0.4, 0.4, 2) * cell
        value = float(rng.choice([rng.uniform(*dark), rng.uniform(*grey)]))
        paint_shape(img, rng, x0, y0, texel, float(cx), float(cy), kind, radius, value)
    img *= 1 + 0.01 * rng.standard_normal(img.shape)  # paper grain
    img = ndimage.gaussian_filter(img, blur_m / texel)
    return Texture(np.clip(img, 0.01, 1.0).astype(np.float32), x0, y0, texel, light)


def table_texture(rng: np.random.Generator, *, x_range: tuple[float, float],
                  y_range: tuple[float, float], texel: float, blur_m: float) -> Texture:
    """A table top (wood grain) with a plate, bowl, cup, cutlery, napkin and placemat on a floor.
    """
    nx = int(round((x_range[1] - x_range[0]) / texel))
    ny = int(round((y_range[1] - y_range[0]) / texel))
    x0, y0 = x_range[0], y_range[0]
    xs = x0 + np.arange(nx) * texel
    ys = y0 + np.arange(ny) * texel
    X, Y = np.meshgrid(xs, ys)
    # floor everywhere, then the 0.75 m x 0.75 m table with wood grain along y
    img = 0.25 * (1 + 0.15 * smooth_noise(rng, (ny, nx), 0.01 / texel))
    table = (X > 0.12) & (X < 0.87) & (np.abs(Y) < 0.375)
    warp = 0.01 * smooth_noise(rng, (ny, nx), 0.05 / texel)
    grain = np.sin(2 * np.pi * (X + warp) / rng.uniform(0.006, 0.01))
    rings = np.sin(2 * np.pi * (X + 3 * warp) / 0.045)
    wood = 0.5 * (1 + 0.03 * grain + 0.06 * rings + 0.03 * smooth_noise(rng, (ny, nx),
                                                                           0.002 / texel))
    img[table] = wood[table]

    def paint(cx: float, cy: float, kind: str, size: float, value: float,
              angle: float | None = None, aspect: float | None = None) -> None:
        paint_shape(img, rng, x0, y0, texel, cx, cy, kind, size, value, angle, aspect)

    def jitter(v: float, d: float = 0.04) -> float:
        return v + float(rng.uniform(-d, d))

    # placemat with a check pattern
    pm = (np.abs(X - jitter(0.45)) < 0.16) & (np.abs(Y - jitter(-0.12)) < 0.11)
    check = ((np.floor(X / 0.04) + np.floor(Y / 0.04)) % 2).astype(np.float64)
    img[pm] = (0.45 + 0.15 * check)[pm]
    # plate with a rim, bowl (dark ring, lighter inside), cup with handle
    px, py = jitter(0.45), jitter(-0.12)
    paint(px, py, 'ellipse', 0.11, 0.92, 0.0, 1.0)
    paint(px, py, 'ellipse', 0.085, 0.8, 0.0, 1.0)
    bx, by = jitter(0.62), jitter(0.15)
    paint(bx, by, 'ellipse', 0.08, 0.12, 0.0, 1.0)
    paint(bx, by, 'ellipse', 0.065, 0.45, 0.0, 1.0)
    paint(bx + 0.015, by - 0.01, 'ellipse', 0.03, 0.7, 0.3, 0.6)
    cx, cy = jitter(0.3), jitter(0.2)
    paint(cx + 0.045, cy, 'rect', 0.02, 0.2, 0.0)
    paint(cx, cy, 'ellipse', 0.04, 0.18, 0.0, 1.0)
    paint(cx, cy, 'ellipse', 0.03, 0.08, 0.0, 1.0)
    # cutlery: long thin bright blades with dark handles
    for k in range(3):
        ux, uy = jitter(0.64 + 0.035 * k, 0.01), jitter(-0.14, 0.02)
        ang = float(rng.uniform(-0.2, 0.2)) + np.pi / 2
        paint(ux, uy, 'rect', 0.09, 0.95, ang, None)
        paint(ux + 0.07 * np.cos(ang), uy + 0.07 * np.sin(ang), 'rect', 0.04, 0.1, ang)
    # napkin with stripes, a book, small items
    nx0, ny0 = jitter(0.22), jitter(-0.22)
    nap = (np.abs(X - nx0) < 0.07) & (np.abs(Y - ny0) < 0.07)
    img[nap] = (0.85 - 0.25 * (np.floor((X - nx0) / 0.012) % 3 == 0))[nap]
    paint(jitter(0.75), jitter(-0.3), 'rect', 0.1, 0.3, float(rng.uniform(0, np.pi)))
    for _ in range(12):
        paint(float(rng.uniform(0.15, 0.85)), float(rng.uniform(-0.36, 0.36)),
              ['poly', 'ellipse', 'star'][int(rng.integers(3))], float(rng.uniform(0.008, 0.025)),
              float(rng.uniform(0.05, 0.95)))
    img = ndimage.gaussian_filter(img, blur_m / texel)
    return Texture(np.clip(img, 0.01, 1.0).astype(np.float32), x0, y0, texel, 0.25)


def natural_texture(rng: np.random.Generator, *, half_extent: float, texel: float,
                    blur_m: float, scales_m: tuple[float, float], slope: float,
                    contrast: float, patches: int, patch_contrast: float,
                    mean: float = 0.4) -> Texture:
    """A natural-like surface: 1/f-like multi-scale log-intensity noise plus edged patches.

    The log irradiance is a sum of smooth noise octaves with correlation lengths from
    ``scales_m[0]`` to ``scales_m[1]`` (doubling), octave amplitudes ∝ length^``slope``
    (``slope`` ≈ 1: a 1/f power spectrum, as in natural images), scaled to the std
    ``contrast``; ``patches`` regions with sharp outlines (thresholded smooth noise, like objects
    or stains) shift it by ±``patch_contrast``.

    Args:
        rng: Random generator.
        half_extent: Half the side of the square textured area, metres.
        texel: Texture resolution, metres.
        blur_m: Optical blur (Gaussian std) in metres on the plane.
        scales_m: Shortest and longest correlation length, metres.
        slope: Exponent of the octave amplitudes (0: white across octaves, 1: 1/f).
        contrast: Std of the log irradiance of the noise part.
        patches: Number of independent patch layers (0: none).
        patch_contrast: Largest log-irradiance step at a patch edge.
        mean: Mean irradiance (1 = white).
    """
    n = int(round(2 * half_extent / texel))
    x0 = y0 = -half_extent
    log_img = np.zeros((n, n))
    length = scales_m[0]
    while length <= scales_m[1] * 1.0001:
        log_img += (length / scales_m[1]) ** slope * smooth_noise(rng, (n, n), length / texel)
        length *= 2.0
    log_img *= contrast / max(float(log_img.std()), 1e-12)
    for _ in range(patches):
        corr = float(rng.uniform(0.03, 0.15)) / texel
        layer = smooth_noise(rng, (n, n), corr) > float(rng.uniform(0.5, 1.5))
        log_img += np.where(layer, float(rng.uniform(-1.0, 1.0)) * patch_contrast, 0.0)
    img = mean * np.exp(log_img - np.log(float(np.mean(np.exp(log_img)))))
    img = ndimage.gaussian_filter(img, blur_m / texel)
    return Texture(np.clip(img, 0.01, 1.0).astype(np.float32), x0, y0, texel, mean)
