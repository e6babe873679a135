import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.skeleton import foliage_skeleton, lift_to_3d
from treeform.skeleton.depth import revolved_radius, skeleton_hull, touches_hull


@pytest.fixture(scope="module")
def lifted(crown):
    mask, _ = crown
    sk = foliage_skeleton(mask, n_branches=5, seed=0)
    base = sk.branches[0][0]
    polys, radii = lift_to_3d(sk, base=base, metres_per_pixel=0.01, seed=0)
    return sk, base, polys, radii


def test_lift_frame_and_shapes(lifted):
    sk, base, polys, radii = lifted
    assert len(polys) == len(radii) == len(sk.branches)
    for b, p, r, w in zip(sk.branches, polys, radii, sk.widths):
        assert p.shape == (len(b), 3) and r.shape == (len(b),)
        np.testing.assert_allclose(p[:, 0], (b[:, 0] - base[0]) * 0.01)
        np.testing.assert_allclose(p[:, 1], (base[1] - b[:, 1]) * 0.01)
        np.testing.assert_allclose(r, w * 0.01)
    assert np.allclose(polys[0][0], 0) and np.all(polys[0][:, 2] == 0)
    assert polys[0][-1, 1] > 0  # Y up


def test_depth_touching_stay_flat_free_reach_the_volume(lifted):
    sk, base, polys, _ = lifted
    hull, x_axis = skeleton_hull(sk)
    touch = touches_hull(sk, hull)
    free = [i for i in range(1, len(sk.branches)) if not touch[i]]
    assert len(free) >= 3 and touch[1:].any()
    for i in range(1, len(sk.branches)):
        z_tip = polys[i][-1, 2] / 0.01
        if touch[i]:
            assert abs(z_tip) < 1e-9
            if sk.order[i] == 1:
                assert np.allclose(polys[i][:, 2], 0)
        else:
            b = sk.branches[i]
            R = revolved_radius(hull, x_axis, [b[-1, 1]])[0]
            assert np.hypot(b[-1, 0] - x_axis, z_tip) == pytest.approx(R, rel=1e-6, abs=1e-6)
        # depth starts at the parent's depth at the attachment
        parent = polys[sk.parent[i]]
        j = np.argmin(((sk.branches[sk.parent[i]] - sk.branches[i][0]) ** 2).sum(1))
        assert polys[i][0, 2] == pytest.approx(parent[j, 2], abs=1e-9)
    signs = np.sign([polys[i][-1, 2] for i in free if abs(polys[i][-1, 2]) > 1e-6])
    assert (signs > 0).any() and (signs < 0).any()


def test_lift_deterministic_and_bad_input(lifted):
    sk, base, polys, _ = lifted
    again, _ = lift_to_3d(sk, base=base, metres_per_pixel=0.01, seed=0)
    assert all(np.array_equal(a, b) for a, b in zip(polys, again))
    with pytest.raises(InputError, match="metres_per_pixel"):
        lift_to_3d(sk, base=base, metres_per_pixel=0)
    with pytest.raises(InputError, match="base"):
        lift_to_3d(sk, base=(1, 2, 3), metres_per_pixel=1)
    with pytest.raises(InputError, match="sk"):
        lift_to_3d({"branches": []}, base=(0, 0), metres_per_pixel=1)


def test_revolved_radius_of_a_square():
    hull = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    np.testing.assert_allclose(revolved_radius(hull, 4.0, [0, 5, 10, 11]), [6, 6, 6, 0])
