"""Synthetic 360-degree panoramas of the archipelago with exact ground truth (stand-in for the ch. 4 videos).

``render_panorama`` draws, for camera poses (x, y, height, heading, pitch, roll), a cylindrical panorama (geometry
in ``core.cylinder``): sky with a vertical gradient and clouds, shaded textured land (forest and rock)
between the virtual horizon and water profiles of ``core.raycast``, a textured sea with waves, distance
haze, sun glare with glitter on the water, blur, exposure changes and pixel noise. The sky/land and land/sea
boundaries are anti-aliased analytically (coverage of each pixel), so edges are exact to a fraction of a pixel.

Ground truth (``PanoramaTruth``): pitch, roll, heading, and per column the horizon and water profiles (tan of
the elevation) and rows, both in the levelled panorama (column u at azimuth heading + 2 pi u / W) and in the
tilted image as rendered.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import kornia
import torch

from core.cylinder import (
    column_azimuths,
    interp_profile,
    panorama_focal,
    row_tangents,
    tangent_to_row,
    tilted_to_level,
)
from core.errors import InputError
from core.raycast import VirtualHorizon, effective_radius

_SKY_HORIZON = (0.80, 0.85, 0.90)
_SKY_ZENITH = (0.28, 0.48, 0.80)
_CLOUD = (0.93, 0.93, 0.95)
_FOREST = (0.12, 0.17, 0.09)
_ROCK = (0.45, 0.42, 0.37)
_SEA_DEEP = (0.05, 0.14, 0.22)
_SEA_FAR = (0.42, 0.52, 0.60)


@dataclass
class Appearance:
    """Per-image rendering conditions; every field is a (B,) tensor.

    Attributes:
        haze: extinction in 1/km (visibility about 3 / haze km); 0 = perfectly clear.
        clouds: cloud cover in [0, 1].
        glare: sun glare and glitter strength in [0, 1].
        sun_azimuth: world azimuth of the sun in rad (clockwise from north).
        sun_elevation: sun elevation in rad.
        exposure: brightness gain (1 = nominal).
        blur: Gaussian blur sigma in px (0 = sharp).
        noise: standard deviation of additive Gaussian pixel noise (image range [0, 1]).
    """

    haze: torch.Tensor
    clouds: torch.Tensor
    glare: torch.Tensor
    sun_azimuth: torch.Tensor
    sun_elevation: torch.Tensor
    exposure: torch.Tensor
    blur: torch.Tensor
    noise: torch.Tensor

    @staticmethod
    def sample(batch: int, degraded: bool = False, generator: torch.Generator | None = None) -> Appearance:
        """Random conditions: clean (light haze, little noise, no glare) or degraded (heavy haze, noise, glare)."""

        def uniform(low: float, high: float) -> torch.Tensor:
            return low + (high - low) * torch.rand(batch, generator=generator, dtype=torch.float64)

        if degraded:
            return Appearance(uniform(0.4, 1.2), uniform(0.3, 1.0), uniform(0.6, 1.0), uniform(0, 2 * math.pi),
                              uniform(0.05, 0.3), uniform(0.6, 1.4), uniform(0.8, 2.0), uniform(0.04, 0.10))
        return Appearance(uniform(0.0, 0.1), uniform(0.0, 0.5), uniform(0.0, 0.0), uniform(0, 2 * math.pi),
                          uniform(0.3, 1.0), uniform(0.9, 1.1), uniform(0.0, 0.5), uniform(0.0, 0.01))

    def to(self, dtype: torch.dtype, device) -> Appearance:
        return Appearance(**{f.name: getattr(self, f.name).to(dtype=dtype, device=device) for f in fields(self)})


@dataclass
class PanoramaTruth:
    """Ground truth of rendered panoramas.

    Attributes:
        pitch, roll, heading: (B,) rad.
        horizon, water: (B, W) tan elevation of the horizon and water profiles per levelled column.
        level_horizon_rows, level_water_rows: (B, W) their rows in the levelled panorama.
        horizon_rows, water_rows: (B, W) rows of the boundaries in each column of the tilted (rendered) image.
    """

    pitch: torch.Tensor
    roll: torch.Tensor
    heading: torch.Tensor
    horizon: torch.Tensor
    water: torch.Tensor
    level_horizon_rows: torch.Tensor
    level_water_rows: torch.Tensor
    horizon_rows: torch.Tensor
    water_rows: torch.Tensor


def _noise(shape: tuple[int, ...], beta: float, anisotropy: float, generator, dtype, device) -> torch.Tensor:
    """Unit-variance fractal noise (B, H, W), periodic; anisotropy > 1 stretches features horizontally."""
    white = torch.randn(shape, generator=generator, dtype=torch.float64).to(device)
    fy = torch.fft.fftfreq(shape[-2], device=device, dtype=torch.float64)[:, None]
    fx = torch.fft.rfftfreq(shape[-1], device=device, dtype=torch.float64)[None, :] * anisotropy
    radius = torch.sqrt(fx**2 + fy**2 + 1e-4)
    field = torch.fft.irfft2(torch.fft.rfft2(white) * radius ** (-beta / 2), s=shape[-2:])
    field = (field - field.mean((-2, -1), keepdim=True)) / field.std((-2, -1), keepdim=True)
    return field.to(dtype)


def _color(rgb: tuple[float, float, float], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(rgb, dtype=like.dtype, device=like.device).view(1, 3, 1, 1)


def _boundary_rows(profile, psi_cam, heading, pitch, roll, height, width, iterations=26) -> torch.Tensor:
    """Rows where each tilted column crosses a level profile (B, N): bisection on tan elevation, (B, W)."""
    batch = profile.shape[0]
    top = row_tangents(height, width, profile.dtype, profile.device)[0]
    lo = torch.full((batch, width), -top.item(), dtype=profile.dtype, device=profile.device)
    hi = torch.full_like(lo, top.item())
    psi = psi_cam.expand(batch, width)
    for _ in range(iterations):
        mid = (lo + hi) / 2
        psi_l, t_l = tilted_to_level(psi, mid, pitch, roll)
        above = t_l > interp_profile(profile, psi_l + heading[:, None])
        hi = torch.where(above, mid, hi)
        lo = torch.where(above, lo, mid)
    return tangent_to_row((lo + hi) / 2, height, width)


def render_panorama(
    caster: VirtualHorizon,
    poses: torch.Tensor,
    width: int = 2048,
    height: int = 256,
    appearance: Appearance | None = None,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, PanoramaTruth]:
    """Render panoramas and their ground truth.

    Args:
        caster: ray caster over the DEM (its ``bins`` sets the profile resolution; use >= ``width``).
        poses: (B, 6) rows (x m, y m, camera height m, heading rad, pitch rad, roll rad); heading is the world
            azimuth (clockwise from north) of the camera's forward axis, i.e. of column 0.
        width, height: panorama size in pixels.
        appearance: rendering conditions (default: ``Appearance.sample(B)``, clean).
        generator: random generator for textures, conditions and noise.

    Returns:
        image (B, 3, H, W) RGB in [0, 1] (dtype of the caster's DEM) and ``PanoramaTruth``.
    """
    if poses.ndim != 2 or poses.shape[1] != 6:
        raise InputError(f"poses must be (B, 6) = (x, y, height, heading, pitch, roll), got {tuple(poses.shape)}")
    if width < 16 or height < 8:
        raise InputError(f"panorama size must be at least 16 x 8 px, got {width} x {height}")
    dtype, device = caster.heights.dtype, caster.heights.device
    poses = poses.to(dtype=dtype, device=device)
    batch = poses.shape[0]
    appearance = (appearance or Appearance.sample(batch, generator=generator)).to(dtype, device)
    cam_h, heading, pitch, roll = poses[:, 2], poses[:, 3], poses[:, 4], poses[:, 5]
    profiles = caster(poses[:, :2], cam_h)
    f = panorama_focal(width)
    r_eff = effective_radius(caster.k, caster.earth_radius)

    psi_cam = column_azimuths(width, dtype, device)
    t_cam = row_tangents(height, width, dtype, device)
    psi_l, t_l = tilted_to_level(
        psi_cam[None, None, :].expand(batch, height, width), t_cam[None, :, None].expand(batch, height, width),
        pitch, roll,
    )
    world_psi = psi_l + heading[:, None, None]
    horizon = interp_profile(profiles.horizon, world_psi)
    water = interp_profile(profiles.water, world_psi)
    land_distance = interp_profile(profiles.horizon_distance, world_psi)
    coverage_sky = ((t_l - horizon) * f + 0.5).clamp(0, 1)[:, None]
    coverage_sea = ((water - t_l) * f + 0.5).clamp(0, 1)[:, None]
    coverage_land = (1 - coverage_sky - coverage_sea).clamp(min=0)

    def noise(beta: float, anisotropy: float = 1.0) -> torch.Tensor:
        return _noise((batch, height, width), beta, anisotropy, generator, dtype, device)[:, None]

    def per_image(x: torch.Tensor) -> torch.Tensor:
        return x[:, None, None, None]

    # Sky: gradient from the horizon to the zenith, clouds stretched horizontally, brighter towards the sun.
    up = (t_l[:, None] / 0.6).clamp(0, 1) ** 0.6
    sky = _color(_SKY_HORIZON, t_l) * (1 - up) + _color(_SKY_ZENITH, t_l) * up
    cloud_field = noise(3.0, anisotropy=4.0)
    threshold = 1.5 - 2.5 * per_image(appearance.clouds)
    cloud = torch.sigmoid((cloud_field - threshold) * 3.0) * (appearance.clouds > 0).to(dtype)[:, None, None, None]
    cloud_shade = 0.85 + 0.1 * noise(2.0)
    sky = sky * (1 - cloud) + _color(_CLOUD, t_l) * cloud_shade * cloud

    # Land: forest and rock texture, lit when the sun is behind the camera, hazier with distance.
    mix = torch.sigmoid(noise(3.0) * 2.0 - 1.0)
    land = _color(_FOREST, t_l) * (1 - mix) + _color(_ROCK, t_l) * mix
    land = land * (1 + 0.25 * noise(1.5))
    facing = -torch.cos(world_psi - appearance.sun_azimuth[:, None, None])
    land = land * (0.6 + 0.5 * facing.clamp(min=0))[:, None]

    # Sea: distance of the sea surface seen below the sea horizon, waves in world coordinates, sky reflection.
    depression = -t_l
    grazing = (depression**2 - 2 * cam_h[:, None, None] / r_eff).clamp(min=0)
    sea_distance = (r_eff * (depression - torch.sqrt(grazing))).clamp(min=1.0)
    sea_distance = torch.where(depression > 0, sea_distance, torch.full_like(sea_distance, 1e5))
    east = sea_distance * torch.sin(world_psi) + poses[:, 0, None, None]
    north = sea_distance * torch.cos(world_psi) + poses[:, 1, None, None]
    wave_dirs = torch.rand((6, 2), generator=generator, dtype=torch.float64).to(device=device, dtype=dtype)
    wave = torch.zeros_like(east)
    for k in range(6):
        angle, phase = wave_dirs[k, 0] * 0.8 + 0.4, wave_dirs[k, 1] * 2 * math.pi
        number = 2 * math.pi / (2.0 + 3.0 * k)
        wave = wave + torch.sin(number * (torch.cos(angle) * east + torch.sin(angle) * north) + phase)
    wave = wave * torch.exp(-sea_distance / 150.0) / 6.0
    far = (1 - depression / 0.2).clamp(0, 1) ** 3
    sea = _color(_SEA_DEEP, t_l) * (1 - far[:, None]) + _color(_SEA_FAR, t_l) * far[:, None]
    sea = sea * (1 + 0.5 * wave[:, None] + 0.08 * noise(1.0, anisotropy=3.0))

    # Haze towards the horizon colour with the distance of the seen surface.
    haze = _color(_SKY_HORIZON, t_l)
    extinction = per_image(appearance.haze) / 1000.0
    land = land + (haze - land) * (1 - torch.exp(-extinction * land_distance[:, None]))
    sea = sea + (haze - sea) * (1 - torch.exp(-extinction * sea_distance.clamp(max=2e4)[:, None]))
    image = coverage_sky * sky + coverage_land * land + coverage_sea * sea

    # Sun glare: a disc with bloom, and glitter on the water below the sun.
    sun_dir = torch.stack([torch.cos(appearance.sun_elevation) * torch.sin(appearance.sun_azimuth),
                           torch.cos(appearance.sun_elevation) * torch.cos(appearance.sun_azimuth),
                           torch.sin(appearance.sun_elevation)], -1)
    norm = torch.sqrt(1 + t_l**2)
    view = torch.stack([torch.sin(world_psi) / norm, torch.cos(world_psi) / norm, t_l / norm], -1)
    angle = torch.acos((view * sun_dir[:, None, None]).sum(-1).clamp(-1, 1))
    bloom = torch.exp(-((angle / 0.04) ** 2)) + 0.35 * torch.exp(-((angle / 0.35) ** 2))
    azimuth_gap = torch.remainder(world_psi - appearance.sun_azimuth[:, None, None] + math.pi, 2 * math.pi) - math.pi
    sparkle = (noise(0.5, anisotropy=3.0) > 1.2).to(dtype)
    glitter = torch.exp(-((azimuth_gap / 0.12) ** 2)) * sparkle[:, 0] * (depression > 0).to(dtype)
    image = image + per_image(appearance.glare) * (bloom + 0.8 * glitter)[:, None]

    # Camera: exposure, blur, noise.
    image = image * per_image(appearance.exposure)
    sigma = appearance.blur.clamp(min=1e-3)
    kernel = 2 * int(math.ceil(3 * sigma.max().item())) + 1
    blurred = kornia.filters.gaussian_blur2d(image, (kernel, kernel), torch.stack([sigma, sigma], -1),
                                             border_type="replicate")
    image = torch.where(per_image(appearance.blur) > 0.05, blurred, image)
    pixel_noise = torch.randn(image.shape, generator=generator, dtype=torch.float64).to(device=device, dtype=dtype)
    image = (image + per_image(appearance.noise) * pixel_noise).clamp(0, 1)

    level_psi = psi_cam[None] + heading[:, None]
    level_h = interp_profile(profiles.horizon, level_psi)
    level_w = interp_profile(profiles.water, level_psi)
    truth = PanoramaTruth(
        pitch=pitch, roll=roll, heading=heading, horizon=level_h, water=level_w,
        level_horizon_rows=tangent_to_row(level_h, height, width),
        level_water_rows=tangent_to_row(level_w, height, width),
        horizon_rows=_boundary_rows(profiles.horizon, psi_cam[None], heading, pitch, roll, height, width),
        water_rows=_boundary_rows(profiles.water, psi_cam[None], heading, pitch, roll, height, width),
    )
    return image, truth

