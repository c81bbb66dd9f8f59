"""Scene loading and validation: every bad field gets one line naming it and the fix."""
import os
import subprocess
import sys

import pytest

from granchain.errors import SceneError
from granchain.scene import load_scene

from conftest import REPO, SCENES, packed


@pytest.mark.parametrize("override, field, words", [
    ("chain.radius=-1", "chain.radius", "must be > 0"),
    ("chain.radius=.nan", "chain.radius", "not a finite number"),
    ("chain.n=1", "chain.n", "below 2"),
    ("effects=[hertz,magic]", "effects[1]", "unknown effect 'magic'"),
    ("effects=[hertz,particle_friction]", "effects", "add rotation"),
    ("effects=[air_drag]", "effects", "'hertz' is missing"),
    ("probes=[2,16]", "probes[1]", "outside the chain of 15"),
    ("probes=[0,13]", "probes[0]", "outside the chain"),
    ("probes=[13,2]", "probes", "before the first"),
    ("probes=[1,13]", "probes[0]", "particle 1 is the striker"),
    ("probes=[2,13,14]", "probes", "exactly two"),
    ("gaps={distribution: list, values: [1.0e-9]}", "gaps.values", "has 1 entries"),
    ("gaps={distribution: uniform}", "gaps.mean", "missing"),
    ("gaps={distribution: gaussian, mean: 1.0e-9}", "gaps.distribution", "unknown distribution"),
    ("gaps={distribution: fixed, mean: -1.0e-9}", "gaps.mean", ">= 0"),
    ("striker.velocity=.nan", "striker.velocity", "not a finite number"),
    ("striker.velocity=-0.1", "striker.velocity", ">= 0"),
    ("striker.velocity=[0.1, 0.2, -1]", "striker.velocity[2]", ">= 0"),
    ("integrator.dt=1e-7", "integrator.dt", "too large"),
    ("integrator.method=euler", "integrator.method", "unknown method"),
    ("material=unobtainium", "material", "unknown material"),
    ("material={E: 200e9, nu: 0.7, rho: 7800}", "material.nu", "above"),
    ("gap.mean=1", "gap", "did you mean 'gaps'"),
    ("drag.form=even", "drag.form", "unknown form"),
    ("output.sample_dt=1e-12", "output.sample_dt", "shorter than the step"),
    ("output.sample_dt=1.0e-6", "output.sample_dt", "cannot resolve the pulse"),
    ("effects=[hertz, rotation, groove_friction, air_drag, particle_friction, rotation]", "effects[5]",
     "listed twice"),
])
def test_validation_errors_name_field_and_fix(override, field, words):
    with pytest.raises(SceneError) as err:
        load_scene(SCENES / "packed-440c.yaml", [override])
    msg = str(err.value)
    assert err.value.field == field
    assert msg.startswith(f"scene field '{field}'")
    assert words in msg
    assert "\n" not in msg and ";" in msg      # problem; fix


def test_gap_list_of_right_length_is_accepted():
    s = load_scene(SCENES / "packed-440c.yaml", ["gaps={distribution: list, values: %s}" % ([1e-9] * 14)])
    assert s.gap_values == tuple([1e-9] * 14)


def test_groove_angle_sets_s():
    s = load_scene(SCENES / "packed-440c.yaml", ["groove.angle_deg=60"])
    assert s.setting("groove_friction").s == pytest.approx(0.5)


def test_cli_error_is_one_line_without_traceback(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("chain: {n: 15, radius: -1}\n")
    p = subprocess.run([sys.executable, "-m", "granchain.cli", "run", str(bad)],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip().count("\n") == 0
    assert "chain.radius" in p.stderr and "Traceback" not in p.stderr


def test_cli_refuses_to_overwrite_results(tmp_path):
    out = tmp_path / "r.json"
    out.write_text("precious")
    p = subprocess.run([sys.executable, "-m", "granchain.cli", "run", str(SCENES / "packed-440c.yaml"),
                        "--set", "striker.velocity=0.2", "--json", "--out", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "--force" in p.stderr
    assert out.read_text() == "precious"


def test_zero_striker_is_valid_and_reports_no_wave():
    from granchain.simulate import run_scene
    r = run_scene(packed(**{"striker.velocity": 0.0}))[0]
    assert r.wave_arrived is False
    # no wave, no peak: every particle's v_max is NaN and flagged, not a measured 0
    assert all(v != v for v in r.v_max) and r.not_final == tuple(range(1, 16))
    assert r.v_g != r.v_g        # NaN: no group velocity without a wave


def test_yaml_syntax_error_is_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("chain: {n: 15\n")
    with pytest.raises(SceneError, match="not valid YAML at line"):
        load_scene(bad)


# ---------------------------------------------------------------------------------------
# Scene.derive
# ---------------------------------------------------------------------------------------
def test_derive_equals_the_scene_written_with_the_change():
    from granchain.scene import scene_from_dict
    raw = {"name": "d", "effects": ["hertz", "rotation", "groove_friction"],
           "integrator": {"method": "adaptive", "tolerance": 1e-9}}
    base = scene_from_dict(raw)
    want = scene_from_dict({**raw, "integrator": {"method": "adaptive", "tolerance": 1e-7},
                            "t_end": 1e-5})
    for d in (base.derive(**{"integrator.tolerance": 1e-7, "t_end": 1e-5}),
              base.derive({"integrator": {"tolerance": 1e-7}, "t_end": 1e-5}),
              base.derive(integrator={"tolerance": 1e-7}, t_end=1e-5)):
        assert d == want and d.spec == want.spec and d.hash == want.hash
    assert base.tolerance == 1e-9 and base.spec["t_end"] == "auto"     # base unchanged
    assert base.derive().hash == base.hash


def test_derive_validates_the_changes():
    base = packed()
    with pytest.raises(SceneError, match="'integrator.metod': unknown key.*integrator.method"):
        base.derive(**{"integrator.metod": "verlet"})
    with pytest.raises(SceneError, match="'integrator.dt'.*too large"):
        base.derive(**{"integrator.dt": 1e-7})
    with pytest.raises(SceneError, match="'integrator.tolerance': has no effect"):
        base.derive(**{"integrator.tolerance": 1e-6})          # rk4: a fixed step
    with pytest.raises(SceneError, match=r"'probes\[1\]'.*outside"):
        base.derive(**{"chain.n": 10})                         # probe 13 is now outside
    # keys of the scene itself are not checked again: verlet keeps adaptive's tolerance
    ad = packed(**{"integrator.method": "adaptive", "integrator.tolerance": 1e-6})
    assert ad.derive(**{"integrator.method": "verlet"}).method == "verlet"


def test_derive_keeps_method_auto_unresolved():
    from granchain.scene import scene_from_dict
    sc = scene_from_dict({"integrator": {"method": "auto"}})
    assert sc.method == "auto" and sc.tolerance == 1e-4
    d = sc.derive(**{"striker.velocity": 0.05})
    assert d.method == "auto" and d.striker_velocities == (0.05,)


def test_scene_layer_does_not_import_the_accuracy_study(tmp_path):
    """Loading a scene with method auto loads neither the cost model nor the study."""
    path = tmp_path / "auto.yaml"
    path.write_text("integrator: {method: auto, tolerance: 1.0e-5}\n")
    code = ("import sys; from granchain.scene import load_scene; sc = load_scene(sys.argv[1]); "
            "assert sc.method == 'auto', sc.method; "
            "print(sorted(m for m in sys.modules if m.startswith('granchain.')))")
    p = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    mods = p.stdout.strip().splitlines()[-1]
    assert "granchain.scene" in mods, p.stdout + p.stderr
    for heavy in ("granchain.costmodel", "granchain.accuracy",
                  "granchain.engines", "granchain.simulate"):
        assert f"'{heavy}" not in mods, mods
