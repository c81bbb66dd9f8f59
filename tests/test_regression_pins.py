"""Regression pins: the engine's own output, and the texts it writes, at an earlier
commit, compared to the last bit or byte.

These are not checks of physics. They say only that nothing changed: the same scenes
give the same bits (fragile across CPUs, compilers and numba versions), the default
scene keeps its hash (so cached results stay valid) and the chapter's chains keep their
LAMMPS decks. Whether the values are right is checked against independent solutions
elsewhere (the chapter's scenes: tests/test_field_scenes.py against
tests/independent.py). Marked ``regression`` and ``slow``: they run in the full suite,
not in the quick tier.
"""
from __future__ import annotations

import hashlib

import pytest

from granchain.lammps import deck as lammps_deck
from granchain.scene import load_scene, scene_from_dict
from granchain.simulate import run_scene
from tests.conftest import SCENES, packed

pytestmark = [pytest.mark.regression, pytest.mark.slow]

ALL = ["hertz", "rotation", "groove_friction", "air_drag", "particle_friction",
       "rolling_friction"]

# v_max of particle 13, its peak time and the balance error of five chapter scenes, on
# the head before per-sphere parameters reached the kernels (every method, every effect):
# the kernels read each sphere's mass, radius and constants from per-chain rows, and
# give these numbers to the last bit. The adaptive method's pin is of the head that made it
# take its samples from its dense output (its steps and so its bits changed by design).
CHAPTER_SCENES = {
    "hertz": {},
    "rk4_all": {"effects": ALL, "rolling": {"k_roll": 100.0},
                "gaps": {"distribution": "uniform", "mean": 20e-9},
                "ensemble": {"realisations": 3}},
    "verlet_all": {"effects": ALL[:5], "integrator": {"method": "verlet", "dt": 1e-9},
                   "gaps": {"distribution": "uniform", "mean": 20e-9},
                   "ensemble": {"realisations": 2}},
    "adaptive": {"effects": ALL[:4], "integrator": {"method": "adaptive"},
                 "gaps": {"distribution": "fixed", "mean": 20e-9}},
    "event": {"effects": ALL[:5], "integrator": {"method": "event"},
              "gaps": {"distribution": "uniform", "mean": 20e-9},
              "ensemble": {"realisations": 2}},
}
PREVIOUS_HEAD = {
    "hertz": (0.06817145133652067, 9.024353935232954e-06, 6.256355021891258e-10),
    "rk4_all": (0.09242858764084441, 1.1819877634168376e-05, 2.7307263016372235e-09),
    "verlet_all": (0.09242856494360384, 1.181987555727536e-05, 6.498681357130116e-07),
    "adaptive": (0.08872001204214702, 1.1607684842960782e-05, 2.620502266990946e-06),
    "event": (0.09242868894711803, 1.1819877100858192e-05, 5.801707486286597e-06),
}


@pytest.mark.parametrize("case", sorted(PREVIOUS_HEAD))
def test_chapter_scenes_give_bit_identical_results(case):
    r = run_scene(scene_from_dict(dict(CHAPTER_SCENES[case], name=case)))[0]
    assert (r.v_max[12], r.t_peak[12], r.energy.balance_error) == PREVIOUS_HEAD[case]


def test_the_default_scene_keeps_its_hash():
    """The hash of the default scene on the head before the field's keys (walls,
    per-sphere radii and materials, precompression) existed: results cached under it
    stay valid."""
    assert scene_from_dict({}).hash == "f36668771dcbdf3e"


# sha256 (first 32 hex digits) of the deck and data texts (outputs dump, binary, none, in
# that order; scene hash replaced by <hash>, plugin path PLUGIN) that commit 41e9852,
# before the field's keys existed, wrote for these scenes, without their comment lines
# (comments name documentation, which may move; the commands and data may not change)
PLUGIN = "/PLUGIN/groove_drag.so"
CHAPTER_DECKS = {
    "packed-440c": "d9599b8d1ab281cd230948c6a91c902e",
    "gaps-20nm-440c": "206e919d2a23f4419b1ca8fa1a78141a",
    "striker-sweep-440c": "3078a97706eca2f0eb4b31aedca335cb",
    "all-effects-list": "86fd41a636e21778700273e925b61d6c",
    "linear-history-auto": "e3b709241e5368249c5c373bf4b588f2",
}
DECK_EFFECTS = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
LIST_GAPS = "[0.0, 20e-9, 5e-9, 0.0, 40e-9, 1e-9, 0.0, 3e-9, 0.0, 10e-9, 7e-9, 0.0, 2e-9, 0.0]"


def _deck_scene(name):
    if name == "all-effects-list":
        return packed(t_end=2e-6, effects=DECK_EFFECTS,
                      **{"rolling.k_roll": 1e3, "gaps.distribution": "list",
                         "gaps.values": LIST_GAPS})
    if name == "linear-history-auto":
        return packed(effects="[hertz, rotation, particle_friction]",
                      **{"contact.tangential": "linear_history", "contact.kt": 1e5})
    return load_scene(SCENES / f"{name}.yaml")


@pytest.mark.parametrize("name", list(CHAPTER_DECKS))
def test_chapter_chains_keep_their_decks_byte_for_byte(name):
    sc = _deck_scene(name)
    h = hashlib.sha256()
    for output in ("dump", "binary", "none"):
        for text in lammps_deck.render(sc, plugin=PLUGIN, output=output):
            lines = text.replace(sc.hash, "<hash>").splitlines()
            h.update("\n".join(ln for ln in lines if not ln.lstrip().startswith("#")).encode()
                     + b"\0")
    assert h.hexdigest()[:32] == CHAPTER_DECKS[name]
