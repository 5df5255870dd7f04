"""One finite-strain body on a quadrilateral mesh, as the one loop holds it: the model, the
integrator (u_r = 0 on the axis, the step following the cells) and its finite-strain force,
for tests that drive the force or the state by hand."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.quad_meshes import one_body
from impact_fenics.stepping import FollowingStep


def finite_body(mesh, material, velocity: tuple[float, float] = (0.0, 0.0),
                t_end: float = 1.0) -> SimpleNamespace:
    """``mesh`` (quadrilaterals) as the body "body" of ``material`` at ``velocity`` (m/s):
    its force, u (owned and ghost entries, m), u_owned, v (m/s), mass (kg), node_xy (m)."""
    model = DeformableModel(one_body(mesh), [Body("body", material)])
    integ = Integrator(model, None, model.axis_dofs(), policy=FollowingStep(None, t_end))
    v0 = np.zeros(model.n_owned)
    v0[0::2], v0[1::2] = velocity
    integ.set_initial(None, v0)
    return SimpleNamespace(mesh=mesh, comm=mesh.comm, V=model.V, model=model, integrator=integ,
                           force=integ.finite[0], coef=integ.finite[0].coef,
                           u_fn=integ.u_function, u_vec=integ.u_vec, v_vec=integ.v_vec,
                           u=integ.u_function.x.array, u_owned=integ.u_owned,
                           v=integ.v_owned, mass=integ.mass, free=integ.free,
                           node_xy=model.node_xy, n_owned=model.n_owned,
                           n_owned_nodes=model.n_owned // 2)


def bar_simulation(mesh, material, t_end: float, velocity=(0.0, 0.0), wall=None,
                   dt: float | None = None, safety: float = 0.5, interval: int = 10,
                   **settings):
    """A Simulation of ``mesh`` (quadrilaterals) as the body "body" of ``material`` at
    ``velocity`` (m/s) to ``t_end`` (s), the step following its cells (``safety`` x the
    current limit every ``interval`` steps) or a fixed ``dt``, on the fixed plane z = 0
    under every boundary node when ``wall`` (a method or its name) is given, as
    scenes.taylor_bar builds it; ``settings``: Settings fields (quiet, no plots, fields or
    timers unless given)."""
    from impact_fenics import scenes
    from impact_fenics.contact.plane import boundary_nodes, plane_below, wall_part
    from impact_fenics.simulation import Settings, Simulation

    model = DeformableModel(one_body(mesh), [Body("body", material)])
    base = dict(quiet=True, plots=False, fields=False, timers=False)
    base.update(settings)
    sim = Simulation(model, Settings(**base), initial_velocity={"body": tuple(velocity)},
                     policy=FollowingStep(None, t_end, dt, safety, interval))
    if wall is not None:
        nodes = boundary_nodes(model.V, model.n_owned // 2)
        method = scenes.make_method(wall) if isinstance(wall, str) else wall
        sim.add_contact(plane_below(mesh.comm, nodes, model.node_xy, model.offset, 0.0,
                                    model.length_scale), method, rigid=wall_part())
    return sim
