"""A finite-strain body on triangles is refused in one line that says why: constant-strain
triangles lock under isochoric plastic flow (tests/test_finite_locking.py measures it),
so finite strain runs on Q1 with mean dilatation. From Python (DeformableModel,
Simulation) and from a scene file (a triangle generator, a .msh file of
triangles): an InputError of one line; from the command line exit 2, one line
"error: ...", no traceback, nothing written."""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import InputError
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.meshing import TaggedMesh
from impact_fenics.simulation import Settings, Simulation
from scene_texts import launch, replace
from test_cli import _disk_msh
from test_finite_scene import TAYLOR

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
REASON = ("finite strain needs quadrilaterals: constant-strain triangles lock under isochoric "
          "plastic flow")
MATERIAL = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)


def triangles() -> dmesh.Mesh:
    return dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([3.2e-3, 32.4e-3])],
                                  [2, 20], cell_type=dmesh.CellType.triangle)


def one_line(error: pytest.ExceptionInfo) -> str:
    text = str(error.value)
    assert "\n" not in text
    return text


def _tagged(mesh: dmesh.Mesh) -> TaggedMesh:
    cmap = mesh.topology.index_map(2)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    cell_tags = dmesh.meshtags(mesh, 2, cells, np.ones(cells.size, dtype=np.int32))
    facet_tags = dmesh.meshtags(mesh, 1, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    return TaggedMesh(mesh, cell_tags, facet_tags, {"bar": 1}, {})


def test_a_finite_strain_body_of_a_small_strain_run_is_refused():
    """The model and the integrator take a finite-strain body on quadrilaterals; the
    small-strain run under a constant step refuses it in one line (its step must follow
    the body's cells)."""
    mesh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([3.2e-3, 32.4e-3])],
                                  [2, 20], cell_type=dmesh.CellType.quadrilateral)
    model = DeformableModel(_tagged(mesh), [Body("bar", MATERIAL)])
    with pytest.raises(InputError) as error:
        Simulation(model, Settings(dt=1e-9, n_steps=1))
    assert one_line(error).startswith("body 'bar' is a finite-strain body: its step follows")


def test_a_finite_strain_body_of_a_model_on_triangles_is_refused():
    mesh = triangles()
    cmap = mesh.topology.index_map(2)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    cell_tags = dmesh.meshtags(mesh, 2, cells, np.ones(cells.size, dtype=np.int32))
    facet_tags = dmesh.meshtags(mesh, 1, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    tm = TaggedMesh(mesh, cell_tags, facet_tags, {"bar": 1}, {})
    with pytest.raises(InputError) as error:
        DeformableModel(tm, [Body("bar", MATERIAL)])
    assert one_line(error) == f"body 'bar': the mesh's cells are triangles: {REASON}"


# the Taylor bar of tests/test_finite_scene.py on triangles: the bar generator, then a .msh
# file of right triangles (the disk of tests/test_cli.py, its group named "bar")
GENERATOR = (('generator = "quad_bar"', 'generator = "bar"'), ("n_r = 2", "h = 1e-3"))
MSH = (('generator = "quad_bar"\nradius = 0.0032\nlength = 0.0324\nn_r = 2',
        'file = "bar.msh"'),)


def scene(tmp, edits) -> list[str]:
    text = TAYLOR
    for old, new in edits:
        text = replace(text, old, new)
    if COMM.rank == 0:
        (tmp / "scene.toml").write_text(text)
        (tmp / "bar.msh").write_text(_disk_msh(3.2e-3, 32.4e-3, 2, 20).replace('"disk"', '"bar"'))
    COMM.barrier()
    return ["run", str(tmp / "scene.toml"), "--quiet", "--out", str(tmp / "out")]


QUAD_OPTIONS = (' or "rod_on_anvil", or quadrilaterals = true (coaxial_bars_sized, shpb, block), '
                'or a mesh file of quadrilaterals')


def expected(tmp, edits) -> str:
    if edits is GENERATOR:
        return ('error: [mesh] generator = "bar": a finite-strain body needs generator = '
                f'"quad_bar"{QUAD_OPTIONS}: {REASON}')
    # a file's cells are counted by the estimate, before anything is written
    return (f'error: [mesh] file = "{tmp / "bar.msh"}": the file\'s cells are triangles '
            f"(recombine its surfaces in gmsh): {REASON}")


@serial_only
@pytest.mark.parametrize("edits", [GENERATOR, MSH], ids=["generator", "msh"])
def test_scene_on_triangles_one_line_exit_2(tmp_path, edits):
    proc = launch(scene(tmp_path, edits))
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert lines == [expected(tmp_path, edits)], proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


@pytest.mark.parametrize("edits", [GENERATOR, MSH], ids=["generator", "msh"])
def test_scene_on_triangles_in_process(tmp_path_factory, capsys, edits):
    tmp = tmp_path_factory.mktemp("tri")
    tmp = type(tmp)(COMM.bcast(str(tmp), root=0))
    with pytest.raises(SystemExit) as exit_:
        cli.main(scene(tmp, edits))
    assert exit_.value.code == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    if COMM.rank == 0:
        assert err == [expected(tmp, edits)], err
    assert not (tmp / "out").exists() and not (tmp / "out.partial").exists()
