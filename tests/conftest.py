import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from granchain.scene import load_scene, scene_from_dict
from granchain.simulate import run_scene

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "granchain" / "scenes"


@pytest.fixture(scope="session")
def repo():
    return REPO


def packed(**over):
    """The chapter's packed 440C chain, Hertz only, with overrides as dotted keys."""
    raw = {"name": "t", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
           "striker": {"velocity": 0.1}, "effects": ["hertz"], "probes": [2, 13],
           "integrator": {"method": "rk4", "dt": 1e-9}}
    from granchain.scene import apply_overrides
    return scene_from_dict(apply_overrides(raw, [f"{k}={v}" for k, v in over.items()]))


def pair(**over):
    """Two spheres, for kernel-level tests. A scene needs n >= 3 (the striker and two
    probes from 2 to n), so this is a valid 3-sphere scene cut to its first two spheres,
    with probes (1, 2) that no scene may give."""
    return dataclasses.replace(packed(**{"chain.n": 3, "probes": "[2, 3]", **over}), n=2,
                               probes=(1, 2))


def run1(scene, **kw):
    return run_scene(scene, **kw)[0]
