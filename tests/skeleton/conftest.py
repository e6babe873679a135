import numpy as np
import pytest


def lobed_crown(n=600):
    """Four round lobes (low-left, mid-right, upper-left, top) around a column, on a stem."""
    yy, xx = np.mgrid[:n, :n]
    lobes = [(200, 440, 85), (400, 330, 85), (190, 250, 80), (320, 120, 85)]
    m = np.zeros((n, n), bool)
    for cx, cy, r in lobes:
        m |= (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
    m |= (abs(xx - 300) <= 40) & (yy >= 120) & (yy <= 480)
    m |= (abs(xx - 300) <= 12) & (yy >= 300) & (yy <= 590)
    return m, lobes


def vine_fingers():
    """Four upright shoots on a horizontal cane: the vine case of seed 004 §3.3."""
    yy, xx = np.mgrid[:300, :400]
    centres = (80, 160, 240, 320)
    m = np.zeros((300, 400), bool)
    for cx in centres:
        m |= (xx - cx) ** 2 / 30 ** 2 + (yy - 120) ** 2 / 100 ** 2 <= 1
    m |= (yy >= 200) & (yy <= 260) & (xx >= 50) & (xx <= 350)
    return m, centres


def _point_polyline_distance(p, poly):
    a, b = poly[:-1], poly[1:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    return float(np.min(np.hypot(*(a + t[:, None] * ab - p).T)))


@pytest.fixture(scope="module")
def crown():
    return lobed_crown()


@pytest.fixture(scope="module")
def fingers():
    return vine_fingers()


@pytest.fixture(scope="session")
def point_polyline_distance():
    """Distance from a point (2,) to an open polyline (K, 2)."""
    return _point_polyline_distance
