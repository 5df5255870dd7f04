"""The paper's studies (docs/results.md): one module per part, sequenced by demos/paper_study.py.

punch       parts 1-2: Sim1/2/3 with every method; the penalty against the coupled bound
bars        part 3: per-pair gaps and forces; sigma_zz against a mesh-converged reference
accuracy    part 4: error against CPU time on three meshes, with the Pareto front
stability   part 5: dt / dt_crit, the penalty's beta, 1e5-step energy drift
modelling   part 6: domain, mesh and punch model against what the scene needs
report      part 7: docs/results.md with the claims table, from the figures' JSON
config      the sizes: FULL (the paper, ~15-20 min on 2 cores) and QUICK (tiny, for tests)
"""
