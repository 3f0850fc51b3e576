"""Source templates of the compiled solvers (not imported): :func:`rig.solvers.compiled.compiled_solver`
copies ``runs.py`` with one method's step (``dp45.py``, ``tsit5.py``, ``dop853.py``, ``rk4.py``, ``euler.py``,
``symplectic_euler.py``, ``rodas4.py``, with the parts they include: ``pair45.py``, ``erk.py``) and a problem's
kernels into a cache module, so that numba can cache the machine code."""
