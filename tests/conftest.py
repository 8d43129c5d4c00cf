"""Shared fixtures: small scenes built in code, the shared real meshes (skipped when absent)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_MODELS = REPO.parent / "shared" / "models"


@pytest.fixture
def shared_models() -> Path:
    if not SHARED_MODELS.is_dir():
        pytest.skip(f"real meshes not available: {SHARED_MODELS} is absent (CI and developers have ../shared)")
    return SHARED_MODELS
