"""Where the MJCF files live: `models/` of the installed package, else of the source checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def models_dir(kind: str) -> Path:
    """The folder of one kind of model file ("mjcf": vehicles, "scenes": worlds): the installed
    package's copy, else the source checkout's."""
    installed = Path(str(resources.files("marinejax"))) / "models" / kind
    if installed.is_dir():
        return installed
    checkout = Path(__file__).resolve().parents[2] / "models" / kind
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"marinejax model files ({kind}) not found in {installed} or {checkout}")
