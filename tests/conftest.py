from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
PHOTOS = SHARED / "photos"


def isolated_photos() -> list[Path]:
    import csv

    path = PHOTOS / "ATTRIBUTION.csv"
    if not path.exists():
        return []
    with open(path) as f:
        return [PHOTOS / r["file"] for r in csv.DictReader(f) if r["isolation_visual"] == "isolated"]


@pytest.fixture
def photos_dir():
    if not PHOTOS.exists():
        pytest.skip("../shared/data/photos is not available")
    return PHOTOS
