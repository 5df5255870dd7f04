"""Round-off bounds of the tests, and the spread of a whole run under a one-ulp change.

Two results that are equal in exact arithmetic are compared in one of three ways:

(a) the two paths evaluate the same expression in the same order (the same code on the
    same numbers, a file that stores every digit): compared exactly;
(b) the two paths differ as expressions (another order of a sum, another formula, another
    partition of a sum over ranks): one step from one state, within
    ``rounding(n, scale)`` = EPS x n x scale, where n counts the roundings on the longer
    path (said where the bound is used) and ``scale`` is the largest magnitude that
    enters them (the sum of the |terms| of a sum: its cancellation is in the count);
(c) two whole runs: a difference of one rounding grows through the steps (a contact node
    that activates a step later, a point that yields a step earlier), by orders of
    magnitude and by an amount no count predicts. The bound is measured: the same run
    again with its initial velocity moved by one ulp (``one_ulp``) gives the spread of
    one rounding; the compared run differs from the reference by roundings at every step,
    and to first order each grows as the one of the first step does (an earlier one has
    longer to grow), so the difference stays within ``n_steps`` x (that spread + a step's
    own roundings of the quantity, the ledger's 32, which is what is left where the
    perturbation does not grow: a conserved energy) (:func:`assert_within_spread`). A
    run that starts at rest gets the one-ulp change in the magnitude of the load that
    drives it instead.

EPS is numpy's machine epsilon (2.2e-16, the spacing of doubles at 1); a rounding errs by
at most EPS / 2 of its result, so EPS per operation leaves a factor 2. A call of exp, log,
sin, cos, sqrt or cbrt counts 4 (numpy's vectorised versions err by up to 4 ulp).
"""
from __future__ import annotations

import numpy as np

EPS = float(np.finfo(float).eps)
LIBM = 4  # roundings counted for one exp, log, sin, cos, sqrt, cbrt
STEP_ROUNDINGS = 32  # a step's roundings of a dof's quantities (see ledger)


def rounding(n: float, scale: float = 1.0) -> float:
    """EPS x n x scale: what n roundings on numbers of size ``scale`` can leave."""
    return EPS * n * scale


def one_ulp(x: float) -> float:
    """``x`` moved by one ulp away from zero (the perturbation of a whole-run bound)."""
    return float(np.nextafter(x, np.inf if x >= 0 else -np.inf))


def spread(ref, perturbed) -> float:
    """Largest |ref - perturbed| (0 for equal arrays)."""
    a, b = np.asarray(ref, dtype=float), np.asarray(perturbed, dtype=float)
    return float(np.abs(a - b).max(initial=0.0))


def assert_within_spread(got, ref, perturbed, n_steps: int, what: str = "",
                         scale: float | None = None) -> None:
    """Class (c): |got - ref| <= n_steps x (spread + 32 EPS x scale), the spread being
    |perturbed - ref|, the same run after a one-ulp change of its start, and 32 EPS x
    scale a step's own roundings of the quantity (scale: the largest |ref| unless given),
    which add up over the steps where the perturbation does not grow (an energy the
    scheme conserves, a column that does not depend on the start)."""
    ref_a = np.asarray(ref, dtype=float)
    if scale is None:
        scale = float(np.abs(ref_a).max(initial=0.0))
    one = spread(ref, perturbed) + rounding(STEP_ROUNDINGS, scale)
    diff = spread(got, ref)
    assert diff <= n_steps * one, (
        f"{what}: differs by {diff:.3g}, above {n_steps} steps x {one:.3g} (the spread of "
        f"a one-ulp change and a step's roundings; scale {scale:.3g})")


def ledger(n_steps: int, n_dofs: int, drifting: bool = False) -> float:
    """Relative bound of a ledger's residual (an identity of the scheme, exact in exact
    arithmetic, summed over a run), EPS x (32 n_steps + 4 n_dofs): each step rounds every
    dof's update (v += dt f / m, u += dt v: 4 roundings), its share of the step's work (a
    product into a running sum: 3), its internal force (a row of K, at most 18 terms for
    P1 triangles; a Q1 cell's 4 points for the finite-strain element) and a contact
    correction (up to 7): 32 in all, on terms within the ledger's scale (a body that
    moves by less than an element: its K u rounds on forces of the size of the strains');
    and each of the four energies of the balance (kinetic, strain or internal work,
    external work, contact) is a sum over the dofs, a rounding per term. The residual
    adds up the steps' roundings: it does not grow with the state's sensitivity as a
    comparison of two runs does.

    ``drifting``: bodies that fly apart rigidly for most of the run (bars after their
    impact) round K u on |K| |u| with |u| = v n dt growing: 18 roundings a step of
    |K| v n dt, whose work over the step is within (omega dt)^2 <= 4 of the kinetic
    energy, n of them: 36 n_steps^2 more."""
    n = STEP_ROUNDINGS * n_steps + 4 * n_dofs + (36 * n_steps ** 2 if drifting else 0)
    return EPS * n


def assert_runs_agree(got, ref, perturbed, n_steps: int, what: str = "",
                      scale: float | None = None) -> None:
    """Two runs of one scene: equal when ``perturbed`` is None (the two evaluate the same
    expressions: one rank, one partition), else :func:`assert_within_spread`."""
    if perturbed is None:
        assert np.array_equal(np.asarray(got, dtype=float), np.asarray(ref, dtype=float)), what
    else:
        assert_within_spread(got, ref, perturbed, n_steps, what, scale)
