"""One trunk where the photo shows one (issue 11 item 2): on every isolated and partial photo of
../shared/data/photos the envelope route's tree crosses the plane at 5 % of its height once (none of these photos
shows several stems at that height). Skipped without the photos. The learned and abs routes' one stem is measured
by benchmarks/eval_photos.py (24 of 24 and 15 of 24 on 2026-11-30) and tested on the sample."""

import csv
from pathlib import Path

import pytest

DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "photos"


def _photos(ratings=("isolated", "partial")) -> list:
    if not (DIR / "ATTRIBUTION.csv").exists():
        return []
    with open(DIR / "ATTRIBUTION.csv") as f:
        return [DIR / r["file"] for r in csv.DictReader(f) if r["isolation_visual"] in ratings]


PHOTOS = _photos()


@pytest.mark.parametrize("photo", PHOTOS, ids=[p.stem for p in PHOTOS])
def test_one_stem_at_the_ground(photo, gl):
    from treeform.methods.envelope.pipeline import reconstruct
    from treeform.metrics.treeform_metrics import stems_at

    assert stems_at(reconstruct(photo, seed=0).skeleton, fraction=0.05) == 1
