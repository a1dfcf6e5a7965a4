"""A finite-element overhead contact line (simple catenary) as the plant: pure numpy/numba.

Modules, one concept each: ``data`` (the parameter set of docs/catenary_data.md §2),
``line`` (mesh, Hermite beam matrices, droppers, static equilibrium, static stiffness),
``pantographs`` (the paper's 2-DOF and the benchmark-like 3-mass lumped pantographs),
``integrator`` (Newmark average acceleration with a moving unilateral penalty contact and
slack droppers as low-rank Woodbury corrections of a once-factorised matrix). The contact-force
statistics are ``pac_common.contact_statistics``'s. See docs/catenary.md.
"""
