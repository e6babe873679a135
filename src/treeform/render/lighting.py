"""How a render is lit: directional lights (a key light with optional shadows) and hemisphere ambient."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.camera import Camera

__all__ = ["Lighting", "MAX_LIGHTS"]


MAX_LIGHTS = 8
"""Directional lights a :class:`Lighting` may hold (key light included)."""


def _vec3(value, name: str) -> tuple:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        v = ()
    if len(v) != 3 or not all(np.isfinite(v)):
        raise InputError(f"{name}: expected 3 finite numbers, got {value!r}")
    return v


@dataclass(frozen=True)
class Lighting:
    """Directional lights plus hemisphere (sky / ground) ambient; Lambert + Blinn-Phong shading.

    Parameters
    ----------
    direction : sequence of 3 floats
        Direction *towards* the key light, in world coordinates (default upper-front-left:
        +Y up, +Z toward the photo's camera, -X left), or in camera coordinates
        (x right, y up, z toward the viewer) when ``camera_relative``.
    key : sequence of 3 floats
        Key light colour times intensity.
    sky, ground : sequence of 3 floats
        Ambient colour for normals pointing straight up / straight down (blended by ``n.y``).
    camera_relative : bool
        Interpret every light direction in the camera's frame, so every view is lit alike.
    lights : sequence of (direction, colour) pairs
        Further directional lights (at most ``MAX_LIGHTS - 1``), each two 3-vectors, in the
        same frame as ``direction`` (seed 003 §4.2.1: up to eight lights).
    shadow : float in [0, 1]
        Strength of the key light's shadows (0: none; 1: the key light is fully blocked):
        a ``shadow_resolution``² shadow map, alpha-tested like the mask, filtered 3x3 (PCF).
    shadow_resolution : int
        Edge of the square shadow map in texels.
    specular : float >= 0
        Weight of the normalised Blinn-Phong highlight; its exponent comes from each
        material's ``roughness`` (``2 / r**4 - 2``, as in Karis 2013).

    Notes
    -----
    ``Lighting(key=(0, 0, 0), sky=(1, 1, 1), ground=(1, 1, 1))`` renders unlit albedo.
    """

    direction: tuple = (-0.5, 0.75, 0.6)
    key: tuple = (0.62, 0.62, 0.58)
    sky: tuple = (0.45, 0.47, 0.52)
    ground: tuple = (0.22, 0.21, 0.19)
    camera_relative: bool = False
    lights: tuple = ()
    shadow: float = 0.0
    shadow_resolution: int = 1024
    specular: float = 0.0

    def __post_init__(self):
        for name in ("direction", "key", "sky", "ground"):
            object.__setattr__(self, name, _vec3(getattr(self, name), f"Lighting.{name}"))
        if not any(self.direction):
            raise InputError(f"Lighting.direction: expected a non-zero vector, got {self.direction!r}")
        try:
            pairs = [tuple(pair) for pair in self.lights]
        except TypeError:
            raise InputError(f"Lighting.lights: expected (direction, colour) pairs, got {self.lights!r}") from None
        if len(pairs) > MAX_LIGHTS - 1:
            raise InputError(f"Lighting.lights: at most {MAX_LIGHTS - 1} lights besides the key, got {len(pairs)}")
        lights = []
        for i, pair in enumerate(pairs):
            if len(pair) != 2:
                raise InputError(f"Lighting.lights[{i}]: expected a (direction, colour) pair, got {pair!r}")
            d = _vec3(pair[0], f"Lighting.lights[{i}] direction")
            if not any(d):
                raise InputError(f"Lighting.lights[{i}]: expected a non-zero direction, got {d!r}")
            lights.append((d, _vec3(pair[1], f"Lighting.lights[{i}] colour")))
        object.__setattr__(self, "lights", tuple(lights))
        if not (isinstance(self.shadow, (int, float)) and 0.0 <= float(self.shadow) <= 1.0):
            raise InputError(f"Lighting.shadow: expected a number in [0, 1], got {self.shadow!r}")
        if not (isinstance(self.specular, (int, float)) and 0.0 <= float(self.specular) < np.inf):
            raise InputError(f"Lighting.specular: expected a finite number >= 0, got {self.specular!r}")
        res = self.shadow_resolution
        if isinstance(res, bool) or not isinstance(res, (int, np.integer)) or not 16 <= res <= 8192:
            raise InputError(f"Lighting.shadow_resolution: expected an integer in [16, 8192], got {res!r}")

    def _to_world(self, d, camera: Camera) -> np.ndarray:
        d = np.asarray(d, np.float64)
        if self.camera_relative:
            r, u, f = camera.axes()
            d = d[0] * r + d[1] * u - d[2] * f
        return d / np.linalg.norm(d)

    def world_direction(self, camera: Camera) -> np.ndarray:
        """Unit vector (3,) towards the key light in world coordinates, for ``camera``."""
        return self._to_world(self.direction, camera)

    def world_lights(self, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Every light, key first: unit directions (L, 3) in world coordinates and colours (L, 3)."""
        dirs = [self.world_direction(camera)] + [self._to_world(d, camera) for d, _c in self.lights]
        cols = [self.key] + [c for _d, c in self.lights]
        return np.array(dirs), np.array(cols, np.float64)
