"""What the training tests share: a Minari datasets directory of their own."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def datasets_dir(tmp_path_factory):
    """``MINARI_DATASETS_PATH`` pointed at a fresh directory for one test module (Minari
    reads it at every call), restored after it."""
    with pytest.MonkeyPatch.context() as patch:
        path = tmp_path_factory.mktemp("minari")
        patch.setenv("MINARI_DATASETS_PATH", str(path))
        yield path
