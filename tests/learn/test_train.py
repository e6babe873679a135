"""Tests of the training code (needs the optional torch extra; skipped without it)."""

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")


@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory, gl):
    from treeform.dataset import generate_dataset

    d = tmp_path_factory.mktemp("data") / "train"
    generate_dataset(d, n=6, size=64, workers=1, seed=3, shard_size=3)
    return d


def _fail_at(step):
    def cb(done, total, info):
        if done == step:
            raise KeyboardInterrupt
    return cb


def test_seg_training_resumes_to_the_same_weights(tmp_path, tiny_data):
    from PIL import Image

    from treeform.dataset.scenes import photo_split
    from treeform.learn.train import train_seg

    photos = tmp_path / "photos"  # real-photo backgrounds: only the 'train' side of the split is read
    photos.mkdir()
    rng = np.random.default_rng(0)
    for name in ("Morus_rubra_1.jpg", "Juglans_nigra_1.jpg"):
        assert photo_split(name) == "train"
        Image.fromarray(rng.integers(0, 255, (48, 64, 3)).astype(np.uint8)).save(photos / name)
    opts = dict(steps=4, batch=2, size=64, chunk=4, repeats=1, checkpoint_every=2, threads=1, width=8,
                photos=photos, photo_fraction=0.5, test_scenes=16)
    a = train_seg(tiny_data, tmp_path / "a", test_data=tiny_data, **opts)
    with pytest.raises(KeyboardInterrupt):
        train_seg(tiny_data, tmp_path / "b", progress=_fail_at(3), **opts)  # killed after the step-2 checkpoint
    # a resume may change only where and how the run goes (checkpoint spacing, device, workers) ...
    from treeform._shared.errors import InputError

    with pytest.raises(InputError, match="other settings"):
        train_seg(tiny_data, tmp_path / "b", **{**opts, "lr": 1e-2})
    # ... resumed with the scenes composed by a worker process: same scenes, so the same weights
    train_seg(tiny_data, tmp_path / "b", test_data=tiny_data, workers=1, **{**opts, "checkpoint_every": 1})
    wa = torch.load(tmp_path / "a" / "checkpoint.pt", weights_only=False)["model"]
    wb = torch.load(tmp_path / "b" / "checkpoint.pt", weights_only=False)["model"]
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    assert (tmp_path / "a" / "model.onnx").stat().st_size > 10_000
    m = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert 0.0 <= m["renders"]["mean_iou"] <= 1.0 and a["renders"]["n"] > 0


def test_rbv_training_writes_an_onnx_that_matches_torch(tmp_path, tiny_data):
    import onnxruntime as ort

    from treeform.learn.nets.masknets import RBVNet
    from treeform.learn.train_masks import train_masknet

    m = train_masknet("rbv", tiny_data, tmp_path / "rbv", test_data=tiny_data, epochs=2, batch=2, threads=1)
    assert len(m["test"]["gt"]["mae_percent"]) == 5
    net = RBVNet()
    net.load_state_dict(torch.load(tmp_path / "rbv" / "checkpoint.pt", weights_only=False)["model"])
    net.eval()
    x = np.random.default_rng(0).random((2, 3, 96, 96)).astype(np.float32)
    sess = ort.InferenceSession(str(tmp_path / "rbv" / "model.onnx"), providers=["CPUExecutionProvider"])
    y = sess.run(None, {"mask": x})[0]
    with torch.no_grad():
        assert np.allclose(y, net(torch.from_numpy(x)).numpy(), atol=1e-4)


@pytest.mark.parametrize("fine_stride", [1, 2, 4])
def test_segnet_gives_logits_at_the_input_size_and_exports_exactly(tmp_path, fine_stride):
    import onnxruntime as ort

    from treeform.learn.export import export_onnx
    from treeform.learn.nets.segnet import SegNet

    torch.manual_seed(0)
    net = SegNet(8, fine_stride=fine_stride).eval()
    x = np.random.default_rng(1).random((1, 3, 48, 72)).astype(np.float32)  # not square, free size
    with torch.no_grad():
        y = net(torch.from_numpy(x)).numpy()
    assert y.shape == (1, 3, 48, 72) and np.isfinite(y).all()
    sess = ort.InferenceSession(str(export_onnx(net, tmp_path / "seg.onnx", kind="seg")),
                                providers=["CPUExecutionProvider"])
    assert np.allclose(sess.run(None, {"image": x})[0], y, atol=1e-4)
    if fine_stride == 1:
        # the sub-pixel head gives each pixel of a stride-2 cell its own logits: a 1-px
        # pattern (here a wood line on every other column) is drawable, which a bilinear
        # upsampling of coarser logits cannot do
        with torch.no_grad():
            net.head.weight.zero_()
            bias = torch.zeros(3, 2, 2)
            bias[2, :, 1] = 1.0  # class 'wood' on the right column of each cell
            net.head.bias.copy_(bias.flatten())
            lab = net(torch.from_numpy(x)).argmax(1)[0].numpy()
        assert (lab[:, 1::2] == 2).all() and (lab[:, 0::2] == 0).all()


def test_segnet_rejects_an_unknown_stride():
    from treeform.learn.nets.segnet import SegNet

    with pytest.raises(ValueError, match="fine_stride"):
        SegNet(8, fine_stride=3)


def test_onnx_weights_load_back_into_the_network_for_fine_tuning(tmp_path):
    import onnxruntime as ort

    from treeform._shared.errors import InputError
    from treeform.learn.export import export_onnx, load_onnx_into
    from treeform.learn.nets.segnet import SegNet

    torch.manual_seed(0)
    src = SegNet(8, fine_stride=4)
    src.train()
    with torch.no_grad():  # give BatchNorm non-trivial statistics, so that folding matters
        for _ in range(3):
            src(torch.rand(4, 3, 64, 64) * 2)
    path = export_onnx(src.eval(), tmp_path / "seg.onnx", kind="seg", example_shape=(1, 3, 64, 64))
    dst = SegNet(8, fine_stride=4)
    load_onnx_into(dst, path, calibrate=torch.rand(4, 3, 64, 64))
    x = torch.rand(1, 3, 48, 64)
    with torch.no_grad():
        ours = dst.eval()(x).numpy()
    ref = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"image": x.numpy()})[0]
    assert np.abs(ours - ref).max() < 1e-4 * max(1.0, np.abs(ref).max())
    with pytest.raises(InputError, match="shape|no weights"):
        load_onnx_into(SegNet(16, fine_stride=4), path, calibrate=torch.rand(2, 3, 64, 64))


def test_a_network_grown_by_the_refinement_starts_as_the_weights_it_grew_from(tmp_path):
    import onnxruntime as ort

    from treeform._shared.errors import InputError
    from treeform.learn.export import export_onnx, load_onnx_into
    from treeform.learn.nets.segnet import SegNet

    torch.manual_seed(0)
    path = export_onnx(SegNet(8).eval(), tmp_path / "seg.onnx", kind="seg", example_shape=(1, 3, 64, 64))
    grown = SegNet(8, refine=6)
    with pytest.raises(InputError, match="no weights for layer full"):  # only where asked for
        load_onnx_into(grown, path, calibrate=torch.rand(2, 3, 64, 64))
    load_onnx_into(grown, path, calibrate=torch.rand(2, 3, 64, 64), new_layers=("full", "refine"))
    x = torch.rand(1, 3, 40, 56)
    ref = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"image": x.numpy()})[0]
    with torch.no_grad():
        assert np.abs(grown.eval()(x).numpy() - ref).max() < 1e-4 * max(1.0, np.abs(ref).max())
        # the correction is live: a non-zero last layer changes single pixels of the logits
        grown.refine[-1].bias.copy_(torch.tensor([0.0, 0.0, 5.0]))
        assert (grown(x).argmax(1) == 2).all()
    with pytest.raises(ValueError, match="refine"):
        SegNet(8, fine_stride=4, refine=6)


def test_unsure_pixels_carry_no_loss():
    from treeform.learn.train import _partial_ce

    torch.manual_seed(0)
    logits = torch.randn(2, 3, 8, 8)
    labels = torch.randint(0, 4, (2, 8, 8), dtype=torch.uint8)
    labels[:, :4] = 255
    other = logits.clone()
    other[:, :, :4] = torch.randn(2, 3, 4, 8) * 5  # anything where the labels are unsure
    assert torch.allclose(_partial_ce(logits, labels, 3.0), _partial_ce(other, labels, 3.0))


def test_tree_dice_weighs_a_small_tree_like_a_large_one():
    from treeform.learn.train import _partial_ce

    labels = torch.zeros(2, 32, 32, dtype=torch.uint8)
    labels[0, 4:30, 4:30] = 1  # a crown that fills the frame
    labels[1, 20:24, 15:17] = 3  # a sapling of 8 pixels (cut-out: tree of unknown part)
    good = torch.full((2, 3, 32, 32), -8.0)
    good[:, 0][labels == 0] = 8.0
    good[:, 1][labels > 0] = 8.0
    missed = good.clone()  # the same, but the sapling called background
    missed[1, 0][labels[1] > 0], missed[1, 1][labels[1] > 0] = 8.0, -8.0
    base = _partial_ce(missed, labels, 3.0) - _partial_ce(good, labels, 3.0)
    dice = _partial_ce(missed, labels, 3.0, tree_dice=0.5) - _partial_ce(good, labels, 3.0, tree_dice=0.5)
    # missing 8 of 2048 pixels is almost free for the cross-entropy; the per-scene Dice term counts it as half
    # of a scene's tree lost: 0.5 x (1 - 1/17) / 2 scenes
    assert base < 0.15 and dice - base > 0.2
    # right answers cost (almost) nothing more with the term
    assert _partial_ce(good, labels, 3.0, tree_dice=0.5) - _partial_ce(good, labels, 3.0) < 0.05


def test_a_checkpoint_from_before_the_new_settings_resumes(tmp_path, tiny_data):
    """Settings added later (bushes, sparse boost, tree Dice) take their defaults for an older checkpoint."""
    from treeform.learn.train import train_seg

    opts = dict(steps=3, batch=2, size=64, chunk=4, repeats=1, checkpoint_every=1, threads=1, width=8)
    with pytest.raises(KeyboardInterrupt):
        train_seg(tiny_data, tmp_path / "r", progress=_fail_at(2), **opts)
    ck = tmp_path / "r" / "checkpoint.pt"
    state = torch.load(ck, weights_only=False)
    for k in ("bush_fraction", "sparse_boost", "tree_dice"):
        del state["config"][k]  # as written before these settings existed
    torch.save(state, ck)
    m = train_seg(tiny_data, tmp_path / "r", **opts)
    assert m["steps"] == 3
    from treeform._shared.errors import InputError

    with pytest.raises(InputError, match="other settings"):
        train_seg(tiny_data, tmp_path / "r", **{**opts, "tree_dice": 0.5})


def test_feet_training_resumes_to_the_same_weights_and_exports_a_detector(tmp_path):
    import shutil
    from pathlib import Path

    from treeform._shared.errors import InputError
    from treeform.dataset.scenes import cutout_split
    from treeform.learn.infer import FeetDetector
    from treeform.learn.train_feet import FeetTrainConfig, train_feet

    src = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "billboards"
    if not src.is_dir():
        pytest.skip("../shared/data/billboards is not available")
    cut = tmp_path / "cutouts"  # a few cut-outs of each side of the split
    cut.mkdir()
    files = sorted(src.glob("*.png"))
    for side in ("train", "test"):
        for f in [f for f in files if cutout_split(f.name) == side][:3]:
            shutil.copy(f, cut / f.name)
    with pytest.raises(InputError, match="multiple of 16"):
        FeetTrainConfig(width=100)
    opts = dict(steps=4, batch=2, width=96, height=64, channels=4, chunk=4, repeats=1, checkpoint_every=2,
                threads=1, test_scenes=2)
    a = train_feet(cut, tmp_path / "a", **opts)
    with pytest.raises(KeyboardInterrupt):
        train_feet(cut, tmp_path / "b", progress=_fail_at(3), **opts)  # killed after the step-2 checkpoint
    with pytest.raises(InputError, match="other settings"):
        train_feet(cut, tmp_path / "b", **{**opts, "lr": 1e-2})
    train_feet(cut, tmp_path / "b", workers=1, **{**opts, "checkpoint_every": 1})
    wa = torch.load(tmp_path / "a" / "checkpoint.pt", weights_only=False)["model"]
    wb = torch.load(tmp_path / "b" / "checkpoint.pt", weights_only=False)["model"]
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    assert a["steps"] == 4 and {"recall", "precision"} <= set(a["test"])
    det = FeetDetector(tmp_path / "a" / "model.onnx")
    assert det.side == 96 and det.detect(np.zeros((64, 96, 3), np.uint8)).shape[1] == 3
    # the ONNX graph computes what the torch network does
    from treeform.learn.nets.feetnet import FeetNet

    net = FeetNet(4).eval()
    net.load_state_dict(wa)
    x = np.random.default_rng(0).random((1, 3, 64, 96)).astype(np.float32)
    with torch.no_grad():
        ref = net(torch.from_numpy(x)).numpy()
    got = det.session.run(None, {"image": x})[0]
    assert np.abs(got - ref).max() < 1e-4
