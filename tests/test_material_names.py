"""Every material by name in a scene file, at the kinematics it has; a class of one's own by
its import path.

Oracles, none taken from the reader under test:

* the registry (impact_fenics.materials.MODELS) against the list of the reference: each
  name at each kinematics is built as its class, or refused in one exact line naming
  the kinematics it has (exit 2 through the command line);
* a value out of the range its class states, a key of another model, a missing one:
  one exact line naming the table and the key;
* exact equivalence of two routes through the same code: the Johnson-Cook Taylor bar
  of scenes/taylor_johnson_cook.toml (coarsened, shortened) and the same run built in
  Python (scenes.taylor_bar); the Drucker-Prager rock of demos/bit_rock.py by name in
  the bit-rock scene and built in Python; the demo's finite-strain material of its own by import
  path (demos/custom_plastic_material.toml) and built in Python. Same mesh, same
  material parameters, same arithmetic: the summaries and histories are equal (==), on
  any number of ranks (both routes partition alike);
* a class of one's own: a good import path builds it with the table's keys; a path
  that does not import, a missing attribute, keys its constructor refuses, no
  kinematics, a missing method of the interface: one line naming the table.
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from conftest import load_demo
from impact_fenics import cli, scene_file
from impact_fenics.errors import InputError
from impact_fenics.materials import MODELS, DruckerPrager, JohnsonCook
from scene_texts import PAIR, ROOT, launch, replace
from test_bit_rock import SCENE as BIT_ROCK_SCENE

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")

# the material table of each name (copper-like constants; a model's own keys)
KEYS = {
    "elastic": "",
    "j2": "yield_stress = 400e6\nhardening = 100e6\n",
    "johnson_cook": ("A = 90e6\nB = 292e6\nn = 0.31\nC = 0.025\nrate0 = 1.0\nm = 1.09\n"
                     "t_room = 293.0\nt_melt = 1356.0\nchi = 0.9\nc_p = 383.0\n"),
    "drucker_prager": ("ucs = 200e6\nfriction_angle = 50.0\ndilatancy_angle = 10.0\n"
                       "tensile_strength = 10e6\n"),
    "neo_hookean": "",
}
CONSTANTS = "E = 124e9\nnu = 0.34\ndensity = 8960.0\n"

# a Taylor bar on 2 x 20 quadrilaterals, 10 us (the face yields)
TAYLOR = """title = "short Taylor bar"
[mesh]
generator = "quad_bar"
radius = 3.2e-3
length = 32.4e-3
n_r = 2

[materials.m]
model = "MODEL"
CONSTANTS
[bodies.bar]
material = "m"
velocity = [0.0, -227.0]
strain = "finite"

[wall]
z = 0.0
method = "film"

[time]
t_end = 1e-5
cfl = 0.5
dt_interval = 10

[output]
fields = false
plots = false
"""


def _text(model: str, strain: str, keys: str | None = None) -> str:
    """A scene whose bodies are of ``model`` at ``strain`` with ``keys`` (default KEYS)."""
    table = f'model = "{model}"\n' + CONSTANTS + (KEYS[model] if keys is None else keys)
    if strain == "finite":
        return TAYLOR.replace('model = "MODEL"\nCONSTANTS\n', table)
    return replace(PAIR, 'E = 200e9\nnu = 0.3\ndensity = 7850.0\n', table).replace(
        "[materials.steel]", "[materials.m]").replace('material = "steel"', 'material = "m"')


def _read(tmp_path, text: str, name: str = "scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return scene_file.read_scene(str(path))


def _refusal(tmp_path, text: str) -> str:
    with pytest.raises(InputError) as exc:
        _read(tmp_path, text)
    return str(exc.value)


def _has(model: str) -> str:
    return "small" if "small" in MODELS[model] else "finite"


ONLY = {"small": 'has a small-strain form only: its body needs strain = "small"',
        "finite": 'has a finite-strain form only: its body needs strain = "finite"'}
CASES = [(model, strain) for model in ("elastic", "j2", "johnson_cook", "drucker_prager",
                                       "neo_hookean") for strain in ("small", "finite")]


@pytest.mark.parametrize("model, strain", CASES, ids=[f"{m}-{s}" for m, s in CASES])
def test_each_name_at_each_kinematics(tmp_path, model, strain):
    """The names of the reference, each at small and finite strain: built as the class of
    its kinematics, or refused in one line naming the kinematics it has."""
    expected = {("elastic", "small"), ("j2", "small"), ("j2", "finite"),
                ("johnson_cook", "finite"), ("drucker_prager", "small"),
                ("neo_hookean", "finite")}
    assert set(MODELS) == {m for m, _ in CASES}
    text = _text(model, strain)
    if (model, strain) in expected:
        spec = _read(tmp_path, text).materials["m"]
        material = spec.material(strain)
        assert type(material) is MODELS[model][strain]
        assert (material.E, material.nu, material.density) == (124e9, 0.34, 8960.0)
        for key, value in (line.split(" = ") for line in KEYS[model].splitlines()):
            assert getattr(material, key) == float(value)
        return
    has = _has(model)
    hint = (' (at finite strain an elastic solid is model = "neo_hookean")'
            if model == "elastic" else "")
    assert _refusal(tmp_path, text) == f'[materials.m] model = "{model}" {ONLY[has]}{hint}'


@serial_only
def test_a_kinematics_refusal_through_the_command_line(tmp_path):
    """One line, exit 2, nothing written."""
    scene = tmp_path / "rock.toml"
    scene.write_text(_text("drucker_prager", "finite"))
    proc = launch(["run", str(scene), "--quiet", "--out", str(tmp_path / "out")])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert lines == ['error: [materials.m] model = "drucker_prager" has a small-strain form '
                     'only: its body needs strain = "small"'], proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


BAD = [
    ("out of range", ("johnson_cook", "finite", KEYS["johnson_cook"].replace("chi = 0.9",
                                                                              "chi = 1.5")),
     "[materials.m] chi = 1.5: must be in [0, 1] (Taylor-Quinney factor: the share of the "
     "plastic work that heats)"),
    ("open bound", ("drucker_prager", "small", KEYS["drucker_prager"].replace(
        "friction_angle = 50.0", "friction_angle = 90.0")),
     "[materials.m] friction_angle = 90.0: must be in [0, 90) (friction angle phi (deg))"),
    ("not a number", ("j2", "small", 'yield_stress = "400 MPa"\n'),
     '[materials.m] yield_stress = "400 MPa": must be a finite number (initial yield stress '
     'sigma_y0 (Pa))'),
    ("two parameters", ("drucker_prager", "small", KEYS["drucker_prager"].replace(
        "dilatancy_angle = 10.0", "dilatancy_angle = 60.0")),
     "[materials.m] dilatancy_angle = 60.0 deg: must lie in [0, friction_angle = 50.0]"),
    ("missing", ("johnson_cook", "finite", KEYS["johnson_cook"].replace("A = 90e6\n", "")),
     "[materials.m] A is missing: yield stress at zero plastic strain, > 0 (Pa)"),
    ("several missing", ("johnson_cook", "finite", KEYS["johnson_cook"].replace(
        "A = 90e6\n", "").replace("chi = 0.9\n", "")),
     "[materials.m] 2 parameters are missing: A (yield stress at zero plastic strain, > 0 "
     "(Pa)); chi (Taylor-Quinney factor: the share of the plastic work that heats, in "
     "[0, 1])"),
    ("key of another model", ("j2", "small", KEYS["j2"] + "A = 1e6\n"),
     '[materials.m] A = 1000000.0: only for model = "johnson_cook"'),
    ("key of two models", ("elastic", "small", "viscosity = 1.0\n"),
     '[materials.m] viscosity = 1.0: only for model = "j2" or "drucker_prager"'),
    ("key of the other kinematics", ("j2", "finite", KEYS["j2"] + "viscosity = 1.0\n"),
     '[materials.m] viscosity = 1.0: the finite-strain form of model = "j2" (FiniteJ2) has '
     "no such parameter (it takes E, nu, density, yield_stress, hardening)"),
    ("unknown name", ("tresca", "small", ""),
     '[materials.m] model = "tresca": use one of elastic, j2, johnson_cook, drucker_prager, '
     'neo_hookean, or a class of your own as "package.module:Class"'),
]


@pytest.mark.parametrize("edit, expected", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_parameters_one_line(tmp_path, edit, expected):
    model, strain, keys = edit
    if model == "tresca":
        text = _text("elastic", strain).replace('model = "elastic"', 'model = "tresca"')
    else:
        text = _text(model, strain, keys)
    message = _refusal(tmp_path, text)
    assert message.startswith(expected), message
    assert "\n" not in message


# ----------------------------------------------------------------------------- exact routes

def _short(text: str) -> str:
    """A shipped Taylor scene on 2 x 20 cells, 10 us, no fields or plots."""
    text = replace(text, "n_r = 8", "n_r = 2")
    text = replace(text, "t_end = 80e-6", "t_end = 10e-6")
    return replace(text, "output_every = 100", "output_every = 100\nfields = false\nplots = false")


SUMMARY = ("n_steps", "dt_range", "t_end", "final_length", "final_face_radius", "eps_p_max",
           "j_min", "energy_initial", "energy", "stored_elastic", "plastic_work")


def _run_scene(text: str, tmp_path, name: str, where: str | None = None) -> dict:
    base = COMM.bcast(str(tmp_path), root=0)
    path = os.path.join(where or base, name)
    if where is None and COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    out = os.path.join(base, name + ".out")
    assert cli.main(["run", path, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def test_johnson_cook_taylor_bar_from_the_scene_is_the_python_route(tmp_path):
    """scenes/taylor_johnson_cook.toml (on 2 x 20 cells, 10 us) and scenes.taylor_bar(...,
    JohnsonCook(...)) with the same numbers: the same summary, exactly (the scene builds
    the same objects; summary.json keeps every double by its repr)."""
    from impact_fenics.scene_keys import ENERGY_EVERY
    from impact_fenics.scenes import taylor_bar
    from impact_fenics.simulation import Settings

    with open(os.path.join(ROOT, "scenes", "taylor_johnson_cook.toml")) as f:
        text = _short(f.read())
    a = _run_scene(text, tmp_path, "jc.toml")
    copper = JohnsonCook(E=124e9, nu=0.34, density=8960.0, A=90e6, B=292e6, n=0.31, C=0.025,
                         rate0=1.0, m=1.09, t_room=293.0, t_melt=1356.0, chi=0.9, c_p=383.0)
    sim = taylor_bar(Settings(quiet=True, plots=False, fields=False, history_every=5,
                              output_every=100, energy_every=ENERGY_EVERY), copper,
                     3.2e-3, 32.4e-3, 2, 227.0, "film", t_end=10e-6, comm=COMM)
    b = sim.run(extra=sim.scene_figures)
    assert a["material"] == "johnson_cook" and a["eps_p_max"] > 0.5  # the face flows
    for key in SUMMARY:
        assert a[key] == b[key], key


def test_custom_finite_material_by_import_path_is_the_python_route(tmp_path):
    """demos/custom_plastic_material.toml names FiniteVoceJ2 by its import path (the module
    beside the scene file): the summary of the Python route, exactly."""
    demo = load_demo("custom_plastic_material")
    a = _run_scene(None, tmp_path, "custom_plastic_material.toml",
                   where=os.path.join(ROOT, "demos"))
    b = demo.taylor(demo.FiniteVoceJ2(**demo.FINITE_VOCE, **demo.COPPER))
    assert a["material"] == "custom_plastic_material:FiniteVoceJ2" and a["eps_p_max"] > 0.5
    for key in SUMMARY:
        assert a[key] == b[key], key


def test_drucker_prager_by_name_is_the_python_route(tmp_path):
    """The bit-rock scene with the Drucker-Prager rock of demos/bit_rock.py by name, and the
    same scene from scenes.bit_rock with DruckerPrager(**GRANITE_DP) on the same mesh:
    equal histories and plastic work (the rock yields under the bit)."""
    from impact_fenics import loads, scenes
    from impact_fenics.simulation import Settings

    rock = load_demo("bit_rock").GRANITE_DP
    table = "".join(f"{k} = {v!r}\n" for k, v in rock.items())
    text = BIT_ROCK.replace("[materials.granite]\nE = 60e9\nnu = 0.25\ndensity = 2600.0\n",
                            '[materials.granite]\nmodel = "drucker_prager"\n' + table)
    assert 'model = "drucker_prager"' in text
    path = os.path.join(COMM.bcast(str(tmp_path), root=0), "bit.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    scene = scene_file.read_scene(path)
    assert scene.materials["granite"].material("small") == DruckerPrager(**rock)
    sim_file = scene_file.build(scene, {"out": None, "quiet": True, "plots": False})
    sim_file.run()
    settings = Settings(dt=sim_file.settings.dt, n_steps=N_BIT, quiet=True, fields=False,
                        plots=False)
    sim_api = scenes.bit_rock(settings, scenes.make_method("film"), rock=DruckerPrager(**rock),
                              bit_radius=0.01, impedance=31866.9,
                              incident=loads.Trapezoid(150e3, 1e-5, 7e-5, 8e-5),
                              tmesh=sim_file.model.tmesh)
    sim_api.run()
    assert sim_file.summary["plastic_dissipation"] > 0.0
    assert sim_file.summary["plastic_dissipation"] == sim_api.summary["plastic_dissipation"]
    a, b = sim_file.history.data(), sim_api.history.data()
    for col in (c for c in a if "cpu_" not in c):  # not the contact's timings
        np.testing.assert_array_equal(a[col], b[col], err_msg=col)


N_BIT = 150
# the tiny bit-rock scene of tests/test_bit_rock.py (150 steps), with a flat bit
BIT_ROCK = BIT_ROCK_SCENE.replace("button = 0.02\n", "")


# ----------------------------------------------------------------------------- one's own class

# a module of the user's, beside the scene file: the demo's classes, and broken ones
USER_MODULE = f"""\
import importlib.util
from dataclasses import dataclass

_spec = importlib.util.spec_from_file_location(
    "custom_plastic_material", {os.path.join(ROOT, "demos", "custom_plastic_material.py")!r})
_demo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_demo)
VoceJ2, FiniteVoceJ2 = _demo.VoceJ2, _demo.FiniteVoceJ2


class NoKinematics:
    def __init__(self, **keys):
        pass


@dataclass(frozen=True)
class NoEnergy(_demo.IsotropicConstants):
    E: float
    nu: float
    density: float
    strain = "finite"
    n_state = 1

    def params(self):
        return None

    def initial_state(self):
        return None

    update = None
"""
VOCE = "sigma_0 = 200e6\nsigma_inf = 400e6\ndelta = 50.0\n"


def _user(tmp_path, model: str, strain: str = "small", keys: str = VOCE) -> str:
    (tmp_path / "user_materials.py").write_text(USER_MODULE)
    return _text("elastic", strain, keys).replace('model = "elastic"', f'model = "{model}"')


def test_own_class_by_import_path(tmp_path):
    """The class is found beside the scene file and gets every key but model."""
    demo = load_demo("custom_plastic_material")
    scene = _read(tmp_path, _user(tmp_path, "user_materials:VoceJ2"))
    spec = scene.materials["m"]
    material = spec.material("small")
    assert type(material).__name__ == "VoceJ2" and spec.plastic
    assert (material.E, material.nu, material.density, material.sigma_0, material.sigma_inf,
            material.delta) == (124e9, 0.34, 8960.0, 200e6, 400e6, 50.0)
    assert material.params().tolist() == demo.VoceJ2(
        E=124e9, nu=0.34, density=8960.0, sigma_0=200e6, sigma_inf=400e6,
        delta=50.0).params().tolist()
    finite = _read(tmp_path, _user(tmp_path, "user_materials:FiniteVoceJ2", "finite"))
    assert type(finite.materials["m"].material("finite")).__name__ == "FiniteVoceJ2"


OWN = [
    ("no such module", ("no_such_module_xyz:Voce", "small", VOCE),
     '[materials.m] model = "no_such_module_xyz:Voce": cannot import no_such_module_xyz '
     "(ModuleNotFoundError: No module named 'no_such_module_xyz')"),
    ("no such class", ("user_materials:Voce", "small", VOCE),
     '[materials.m] model = "user_materials:Voce": the module user_materials ('),
    ("not a path", ("user_materials:Voce:J2", "small", VOCE),
     '[materials.m] model = "user_materials:Voce:J2": not an import path '
     '"package.module:Class"'),
    ("a key the constructor does not take", ("user_materials:VoceJ2", "small",
                                             VOCE + "sigma_1 = 1.0\n"),
     "[materials.m] user_materials:VoceJ2(E, nu, density, sigma_0, sigma_inf, delta, "
     "sigma_1): "),
    ("a key the constructor refuses", ("user_materials:VoceJ2", "small",
                                       VOCE.replace("400e6", "100e6")),
     "[materials.m] user_materials:VoceJ2(E, nu, density, sigma_0, sigma_inf, delta): need "
     "0 < sigma_0 <= sigma_inf (Pa) and delta >= 0"),
    ("no kinematics", ("user_materials:NoKinematics", "small", ""),
     '[materials.m] model = "user_materials:NoKinematics": NoKinematics states no kinematics: '
     'give the class strain = "small" or strain = "finite"'),
    ("the other kinematics", ("user_materials:FiniteVoceJ2", "small", VOCE),
     '[materials.m] model = "user_materials:FiniteVoceJ2" has a finite-strain form only: its '
     'body needs strain = "finite"'),
    ("a method missing", ("user_materials:NoEnergy", "finite", ""),
     '[materials.m] model = "user_materials:NoEnergy": the material has no attribute '
     "'energy' (a finite-strain material needs density, wave_speed, n_state, params, "
     "initial_state, update, energy)"),
]


@pytest.mark.parametrize("edit, expected", [c[1:] for c in OWN], ids=[c[0] for c in OWN])
def test_own_class_refusals_one_line(tmp_path, edit, expected):
    message = _refusal(tmp_path, _user(tmp_path, *edit))
    assert message.startswith(expected), message
    assert "\n" not in message


@serial_only
def test_own_class_refusal_through_the_command_line(tmp_path):
    scene = tmp_path / "own.toml"
    scene.write_text(_user(tmp_path, "no_such_module_xyz:Voce"))
    proc = launch(["run", str(scene), "--quiet", "--out", str(tmp_path / "out")])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith('error: [materials.m] model = "no_such_module_xyz:Voce": cannot '
                               "import"), proc.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()
