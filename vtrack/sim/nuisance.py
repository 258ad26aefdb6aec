"""The nuisances a real traffic camera adds, as named options of `vtrack synth`, and the
image-level ones (camera shake, exposure drift, sensor noise) as small generators.

Shake: the image moves by a random walk (Ornstein-Uhlenbeck, x' = -x / tau + sigma
sqrt(2 / tau) w) plus a vibration (a few sinusoids of 3-9 Hz). Exposure: the sunlight
drifts with clouds (exp of an Ornstein-Uhlenbeck process) and the camera's auto-exposure
chases a target mean brightness with a lag: g' = (g* - g) / tau_ae, g* = (m_ref / m)^0.6.
"""

from __future__ import annotations

import math

import numpy as np

from vtrack.errors import InputError

NUISANCES = {
    "shadows": "vehicles (and trees, signs) cast shadows, one sun direction per clip",
    "exposure": "clouds change the light; the camera's auto-exposure chases it with a lag",
    "shake": "the camera sways a few pixels: random walk plus vibration",
    "noise": "sensor noise",
    "compression": "strong MJPG compression (quality drawn 30..70 unless --quality is given)",
    "inview": "vehicles are already in view (and queued) in frame 1",
    "parked": "vehicles parked on the shoulder in frame 1 pull out during the clip",
    "vegetation": "trees and bushes sway in the wind",
    "mix": "motorcycles, cars, vans and trucks (without it: cars only)",
}


def parse_nuisances(text: str) -> frozenset[str]:
    """`all`, `none` or a comma-separated list of NUISANCES names."""
    text = text.strip()
    if text == "all":
        return frozenset(NUISANCES)
    if text in ("none", ""):
        return frozenset()
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in NUISANCES]
    if unknown:
        raise InputError(f"--nuisance: unknown name {unknown[0]!r} (use all, none or a comma "
                         f"list of {', '.join(NUISANCES)})")
    return frozenset(names)


def shake_offsets(rng: np.random.Generator, frames: int, fps: float,
                  scale: float) -> np.ndarray:
    """Image displacement (frames, 2) in pixels (module docstring); `scale` = width / 640."""
    tau, sigma = rng.uniform(1.0, 3.0), rng.uniform(0.8, 2.0) * scale
    dt = 1.0 / fps
    decay = math.exp(-dt / tau)
    kick = sigma * math.sqrt(1 - decay ** 2)
    walk = np.zeros((frames, 2))
    x = rng.standard_normal(2) * sigma
    for n in range(frames):
        walk[n] = x
        x = x * decay + kick * rng.standard_normal(2)
    t = np.arange(frames)[:, None] / fps
    freq = rng.uniform(3.0, 9.0, (1, 3))
    amp = rng.uniform(0.15, 0.5, (2, 3)) * scale
    phase = rng.uniform(0, 2 * np.pi, (2, 3))
    vib = np.stack([(amp[i] * np.sin(2 * np.pi * freq[0] * t + phase[i])).sum(1)
                    for i in range(2)], 1)
    return walk + vib


class Exposure:
    """Cloud light and auto-exposure (module docstring); `gain(frame)` per frame in order."""

    def __init__(self, rng: np.random.Generator, fps: float) -> None:
        self.rng, self.dt = rng, 1.0 / fps
        self.tau_cloud, self.sigma_cloud = rng.uniform(2.0, 6.0), rng.uniform(0.04, 0.12)
        self.tau_ae = rng.uniform(0.4, 1.5)
        self.cloud = rng.standard_normal() * self.sigma_cloud
        self.gain_ae = 1.0
        self.reference: float | None = None

    def gain(self, mean: float) -> float:
        """This frame's overall gain, given the frame's mean brightness before it."""
        light = math.exp(self.cloud)
        decay = math.exp(-self.dt / self.tau_cloud)
        self.cloud = (self.cloud * decay + self.sigma_cloud * math.sqrt(1 - decay ** 2)
                      * self.rng.standard_normal())
        seen = max(mean * light, 1.0)
        if self.reference is None:
            self.reference = seen
        target = (self.reference / seen) ** 0.6
        self.gain_ae += (target - self.gain_ae) * min(1.0, self.dt / self.tau_ae)
        return light * self.gain_ae


class NoiseBank:
    """Sensor noise: a few padded fields of integer Gaussian noise drawn once and shifted by
    up to `pad` pixels each frame (fresh noise every frame would dominate the render time)."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, int, int], sigma: float,
                 bank: int = 4, pad: int = 16) -> None:
        h, w, c = shape
        self.rng, self.shape, self.bank_size, self.pad = rng, shape, bank, pad
        noise = rng.standard_normal((bank, h + pad, w + pad, c), dtype=np.float32) * sigma
        self.bank = np.clip(np.round(noise), -127, 127).astype(np.int8)

    def sample(self) -> np.ndarray:
        """This frame's noise (h, w, c) int8: a randomly chosen, shifted window."""
        h, w = self.shape[:2]
        i, dy, dx = self.rng.integers([self.bank_size, self.pad + 1, self.pad + 1])
        return self.bank[i, dy:dy + h, dx:dx + w]
