"""The fixed-step kernels measure the observables on the fly (``kernels.run_blocks`` with
observe, no trace asked for): the results must equal, float for float, those of the
Python summariser (``observables.sampled_peaks``, ``wall_peak``, ``energy_ledger``) on the
sampled record of the same chains (trace on), which stays the oracle."""
import math

import numpy as np
import pytest

from granchain.engines import reference
from granchain.gaps import member_gaps, member_radii, members
from granchain.observables import summarize
from granchain.scene import load_scene

from conftest import SCENES

ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction]"

# (scene file, overrides): packed, gapped, end wall with a preload, a dimer chain of two
# materials and radii, contact damping, a radius spread, and a fixed t_end that cuts the
# wave off inside the chain (peaks not final)
CASES = {
    "packed": ("packed-440c.yaml", ["striker.velocity=[0.0, 0.03, 0.1]",
                                    "ensemble.realisations=1"]),
    "gapped": ("gaps-20nm-440c.yaml", ["striker.velocity=[0.05, 0.1]",
                                       "ensemble.realisations=3"]),
    "wall": ("packed-440c.yaml", ["walls.end=ss440c", "precompression.force=0.01",
                                  "striker.velocity=[0.03, 0.1]"]),
    "dimer": ("packed-440c.yaml", ["chain.materials=[ss440c, brass, ss440c, brass, ss440c, "
                                   "brass, ss440c, brass, ss440c, brass, ss440c, brass, "
                                   "ss440c, brass, ss440c]",
                                   "chain.radius=[150.0e-6, 189.0e-6, 150.0e-6, 189.0e-6, "
                                   "150.0e-6, 189.0e-6, 150.0e-6, 189.0e-6, 150.0e-6, "
                                   "189.0e-6, 150.0e-6, 189.0e-6, 150.0e-6, 189.0e-6, "
                                   "150.0e-6]", "material=null"]),
    "damped": ("gaps-20nm-440c.yaml", [f"effects=[hertz, groove_friction, air_drag, rotation, "
                                       "particle_friction, contact_damping]",
                                       "damping.e=0.9", "ensemble.realisations=3"]),
    "spread": ("packed-440c.yaml", ["chain.radius_spread={distribution: normal, sd: 1.0e-6}",
                                    "ensemble.realisations=3"]),
    "timeout": ("gaps-20nm-440c.yaml", ["t_end=6.0e-6", "ensemble.realisations=4"]),
}


def _scene(case, method):
    name, sets = CASES[case]
    return load_scene(SCENES / name, sets + [f"integrator.method={method}"])


def _runs(sc, trace):
    mem = members(sc)
    kw = {"trace": trace, "progress": False}
    radii = member_radii(sc, mem)
    if radii is not None:
        kw["radii"] = radii
    vs = np.array([m.v_striker for m in mem])
    return list(reference.run(sc, member_gaps(sc, mem), vs, **kw))


def _same(a, b) -> bool:
    """Equal floats (NaN equal to NaN), tuples elementwise, other values by ==."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


def _differences(ra, rb) -> list[str]:
    ja, jb = ra.to_json(), rb.to_json()
    return [k for k in ja if k != "wall_s" and not _same(ja[k], jb[k])]


@pytest.mark.parametrize("method", ["rk4", "verlet"])
@pytest.mark.parametrize("case", list(CASES))
def test_on_the_fly_observables_equal_the_summariser_on_the_trace(case, method):
    sc = _scene(case, method)
    traced = _runs(sc, True)
    fly = _runs(sc, False)
    assert all(t.observed is None for t in traced)
    assert all(t.observed is not None and t.t.size <= 2 for t in fly)
    for a, b in zip(traced, fly):
        ra, rb = summarize(a, sc.probes), summarize(b, sc.probes)
        assert _differences(ra, rb) == [], (case, method)
        assert b.status == a.status and b.steps == a.steps
        assert np.array_equal(b.v[-1], a.v[-1]) and np.array_equal(b.energy[0], a.energy[0])
    res = [summarize(t, sc.probes) for t in traced]
    if case == "timeout":
        # peaks cut off inside the chain and after it: NaN on both paths
        assert all(0 < len(r.not_final) < sc.n - 1 for r in res)
    if case == "wall":
        assert all(r.wall_peak_final for r in res if r.v_striker > 0)


def test_a_chain_whose_record_ring_overflows_is_summarised_from_its_trace(monkeypatch):
    """With a ring of 2 record samples the rising edges overflow it: those chains run
    again with their trace, and the results are still the summariser's."""
    sc = _scene("gapped", "verlet")
    traced = _runs(sc, True)
    monkeypatch.setattr(reference, "RECORD_RING", 2)
    fly = _runs(sc, False)
    assert any(t.observed is None for t in fly)          # the fallback ran
    for a, b in zip(traced, fly):
        assert _differences(summarize(a, sc.probes), summarize(b, sc.probes)) == []
