"""The event method in SIMD lanes (``events.run_events_lanes``) against the same method one
chain per thread (``events.run_events``): two separate kernels that must give the same
chain the same result to the last bit, whatever its lane, its block, its neighbours and
the width of the blocks."""
import numpy as np
import pytest

from granchain.engines import reference
from granchain.scene import scene_from_dict

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
EVENT = {"method": "event", "tolerance": 1e-6}
FIELDS = ("v_max", "t_peak", "t_front", "plateau", "final")


def _scene(**over):
    raw = {"name": "lanes", "material": "ss440c", "chain": {"n": 12, "radius": 150e-6},
           "striker": {"velocity": 0.1}, "effects": ALL, "probes": [2, 11],
           "integrator": EVENT}
    raw.update(over)
    if "materials" in raw["chain"]:
        del raw["material"]              # the list gives every sphere's material
    return scene_from_dict(raw)


SCENES = {
    "gapped-all-effects": _scene(),
    "hertz-only": _scene(effects=["hertz"]),
    "rolling": _scene(effects=ALL + ["rolling_friction"], rolling={"k_roll": 1e3}),
    "dimer-brass": _scene(chain={"n": 12, "radius": [150e-6, 120e-6] * 6,
                                 "materials": ["ss440c", "brass"] * 6}),
    "damped": _scene(effects=ALL + ["contact_damping"],
                     damping={"model": "coeff_restitution", "e": 0.9}),
    "cut-off": _scene(t_end=4e-6),
    # the effects that locate switches of a contact law of their own
    "plastic": _scene(material="ss316",
                      effects=["hertz", "groove_friction", "air_drag", "rotation",
                               "plastic_contact"]),
    "jkr": _scene(effects=["hertz", "groove_friction", "air_drag", "rotation", "adhesion"],
                  adhesion={"model": "jkr", "surface_energy": 1.0}),
    "dmt": _scene(effects=ALL + ["adhesion"], adhesion={"model": "dmt", "surface_energy": 1.0}),
}


def _ensemble(B=21, seed=0):
    rng = np.random.default_rng(seed)
    gaps = rng.uniform(0.0, 60e-9, (B, 11))
    gaps[3] = 0.0                                   # a packed member
    vs = rng.choice([0.02, 0.1, 0.5], B)            # members of different lengths
    vs[5] = 0.0                                     # a striker at rest: no step at all
    return gaps, vs


def _key(t):
    o = t.observed
    return (tuple(np.asarray(getattr(o, f)).tobytes() for f in FIELDS),
            o.balance_error, t.steps, t.rejected, t.force_evaluations, t.status,
            t.v[-1].tobytes(), t.energy[-1].tobytes(), float(t.t[-1]))


@pytest.mark.parametrize("case", sorted(SCENES))
def test_lanes_give_the_one_chain_kernel_bit_for_bit(case, monkeypatch):
    scene = SCENES[case]
    gaps, vs = _ensemble()
    one = [_key(t) for t in reference.run(scene, gaps, vs, progress=False, lanes=False)]
    for width in (8, 3):
        monkeypatch.setattr(reference, "EVENT_LANES", width)
        got = [_key(t) for t in reference.run(scene, gaps, vs, progress=False)]
        bad = [b for b in range(len(vs)) if got[b] != one[b]]
        assert not bad, f"{case}, {width} lanes: members {bad} differ from the one-chain kernel"
    statuses = {k[5] for k in one}
    if case == "cut-off":
        assert "done" in statuses or "timeout" in statuses


def test_a_member_alone_is_bit_identical_to_its_run_in_the_ensemble():
    """The error scales of a chunk follow its fastest striker, so an ensemble of one speed
    (a study's batch): each member alone gives its result in the ensemble, bit for bit."""
    scene = SCENES["gapped-all-effects"]
    gaps, _ = _ensemble(B=30, seed=4)
    vs = np.full(len(gaps), 0.1)
    whole = [_key(t) for t in reference.run(scene, gaps, vs, progress=False)]
    for b in (0, 7, 29):
        alone = [_key(t) for t in reference.run(scene, gaps[b:b + 1], vs[b:b + 1],
                                                progress=False)]
        assert alone == [whole[b]]


def test_lanes_change_nothing_but_speed_on_a_long_queue(monkeypatch):
    """More chains than lanes times threads: lanes are refilled many times over."""
    monkeypatch.setattr(reference, "EVENT_LANES", 4)
    scene = SCENES["hertz-only"]
    gaps, vs = _ensemble(B=61, seed=9)
    a = [_key(t) for t in reference.run(scene, gaps, vs, progress=False)]
    b = [_key(t) for t in reference.run(scene, gaps, vs, progress=False, lanes=False)]
    assert a == b
