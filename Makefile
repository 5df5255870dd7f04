# impact_fenics: set-up, the main demo, the tests.
VENV ?= .venv
PY := $(VENV)/bin/python
MPIRUN := scripts/mpirun.sh
NP ?= 2

.PHONY: setup demo test test-serial test-mpi study study-taylor study-taylor-anvil study-shpb study-upsetting study-upsetting-finite study-hertz-cylinder study-prandtl-punch docs clean setup-modern demo-modern test-modern

setup:
	@scripts/setup.sh

# the main job: the 1D-wave check of the explicit scheme, then the thick-bar impact
demo: setup
	$(MPIRUN) -n $(NP) $(PY) demos/elastic_wave.py --out results/elastic_wave
	$(MPIRUN) -n $(NP) $(PY) demos/bar_impact.py --method film --out results/bar_impact

test: setup
	$(MAKE) --no-print-directory test-serial test-mpi

test-serial:
	$(PY) -m pytest tests -q

test-mpi:
	N=$(NP) PY=$(PY) scripts/mpi_pytest.sh tests -q

# the paper's studies: docs/figures/*.png|json and docs/results.md (about 10-20 min on 2 cores)
study: setup
	$(MPIRUN) -n $(NP) $(PY) demos/paper_study.py

# the same on the current FEniCSx (dolfinx 0.11, PETSc 3.25, MPICH: PyPI wheels on
# Python >= 3.12, in .venv-modern); the launcher is the MPICH mpiexec of that venv
MODERN_PY := .venv-modern/bin/python

setup-modern:
	@scripts/setup_modern.sh

demo-modern: setup-modern
	$(MPIRUN) -n $(NP) $(MODERN_PY) demos/elastic_wave.py --out results/modern/elastic_wave
	$(MPIRUN) -n $(NP) $(MODERN_PY) demos/bar_impact.py --method film --out results/modern/bar_impact

test-modern: setup-modern
	$(MAKE) --no-print-directory test-serial test-mpi PY=$(MODERN_PY)

# the Taylor bar on three meshes against the literature (tests/test_taylor_study.py; long)
study-taylor: setup
	$(PY) -m pytest tests/test_taylor_study.py -m study -q -s

# the Taylor rod onto a steel anvil whose E and density are scaled by 1, 10, ..., 10^4,
# against the rigid wall (tests/test_taylor_anvil_study.py, docs/taylor_bar.md,
# docs/figures/taylor_anvil.json; about 3 minutes on one core)
study-taylor-anvil: setup
	$(PY) -m pytest tests/test_taylor_anvil_study.py -m study -q -s

# the SHPB's recovered J2 curve on the shipped and the halved mesh against the law
# (tests/test_shpb_study.py), and friction mu = 0, 0.1, 0.2 at the specimen's faces against
# the slab estimate, writing docs/figures/shpb_friction_*.png|json
# (tests/test_shpb_friction_study.py), and the finite-strain specimen of
# scenes/shpb_finite.toml (tests/test_shpb_finite.py), and L/D = 1 against 0.5, the
# specimen's inertia (tests/test_shpb_inertia.py); docs/shpb.md; a few minutes on 2 cores
study-shpb: setup
	N=$(NP) PY=$(PY) scripts/mpi_pytest.sh tests/test_shpb_study.py tests/test_shpb_friction_study.py tests/test_shpb_finite.py tests/test_shpb_inertia.py -m study -q -s

# upsetting with Coulomb friction (small strain) against the slab estimate
# (tests/test_upsetting_study.py, docs/friction.md; a few minutes on one core)
study-upsetting: setup
	$(PY) -m pytest tests/test_upsetting_study.py -m study -q -s

# upsetting at finite strain, 10-30 % reduction, against the slab estimate
# (tests/test_upsetting_finite_study.py, docs/friction.md; about seven minutes on one core)
study-upsetting-finite: setup
	$(PY) -m pytest tests/test_upsetting_finite_study.py -m study -q -s

# Hertz's line contact in plane strain: a cylinder pressed slowly on the wall and on a
# block (node to segment), 5, 10, 20 nodes across b (tests/test_plane_strain_hertz_study.py,
# docs/plane_strain.md; about 20 s on one core)
study-hertz-cylinder: setup
	$(PY) -m pytest tests/test_plane_strain_hertz_study.py -m study -q -s

# the Prandtl punch in plane strain: a flat rigid punch on a J2 block, three meshes, the
# corner cell halved each time (tests/test_plane_strain_punch.py, docs/plane_strain.md;
# about five minutes on one core)
study-prandtl-punch: setup
	$(PY) -m pytest tests/test_plane_strain_punch.py -m study -q -s

# the generated pages: docs/scenes.md from the scene reader's table of keys, and
# docs/performance.md from docs/bench.json (BENCH=results/bench.json takes a new benchmark
# run, `python -m impact_fenics.bench`, first); tests/test_docs_pages.py checks both
docs: setup
	$(PY) -m impact_fenics.docs_pages $(if $(BENCH),--bench $(BENCH))

clean:
	rm -rf results .pytest_cache
