"""Explicit Runge–Kutta stage arithmetic unrolled per state size (generated source, cached).

For 4–6 states CPython spends more time iterating ``zip`` generators than doing arithmetic; writing
every component out (as ``dataclasses``/``namedtuple`` do for their methods) makes a step ~2.5× cheaper.
:func:`rk_kernels` builds, for an explicit tableau and a state size n, two functions:

* ``stages(fun, t, y, k1, h) -> (y_new, y_last_stage, k2, ..., k_s)``: all stages and the solution;
* ``error_norm(y, y_new, k1, ..., k_s, k_fsal, h, rtol, atol) -> float``: RMS of
  h·Σ e_i k_i / (atol + rtol·max(|y|, |y_new|)) (scipy's norm).
"""
from __future__ import annotations

from functools import cache
from typing import Callable


def _lin(terms: list[tuple[str, str]]) -> str:
    """'c1*x1 + c2*x2 ...' for nonzero coefficients (names)."""
    return " + ".join(f"{c}*{x}" for c, x in terms) or "0.0"


@cache
def rk_kernels(A: tuple[tuple[float, ...], ...], B: tuple[float, ...], C: tuple[float, ...],
               E: tuple[float, ...], n: int) -> tuple[Callable, Callable]:
    """Generated (stages, error_norm) for the tableau A (rows 2..s, lower triangle), weights B (s),
    nodes C (s), error weights E (s + 1, the last for the FSAL stage) and n states."""
    s = len(B)
    if not (len(A) == s - 1 and len(C) == s and len(E) == s + 1 and n >= 1):
        raise ValueError(f"rk_kernels: inconsistent tableau sizes (A {len(A)}, B {len(B)}, C {len(C)}, "
                         f"E {len(E)}) or n = {n}")
    ns: dict = {}
    lines = ["def stages(fun, t, y, k1, h):", f"    {', '.join(f'y{i}' for i in range(n))}, = y",
             f"    {', '.join(f'k1_{i}' for i in range(n))}, = k1"]
    for j in range(2, s + 1):                     # stage j uses a[j][0..j-2]
        row = A[j - 2]
        coef = []
        for m, a in enumerate(row[: j - 1]):
            if a != 0.0:
                ns[f"a{j}_{m + 1}"] = a
                lines.append(f"    h{j}_{m + 1} = h*a{j}_{m + 1}")
                coef.append((f"h{j}_{m + 1}", m + 1))
        comps = [f"y{i} + " + _lin([(c, f"k{m}_{i}") for c, m in coef]) for i in range(n)]
        ns[f"c{j}"] = C[j - 1]
        lines.append(f"    ys{j} = ({', '.join(comps)},)")
        lines.append(f"    k{j} = fun(t + c{j}*h, ys{j})")
        lines.append(f"    {', '.join(f'k{j}_{i}' for i in range(n))}, = k{j}")
    bt = []
    for m, b in enumerate(B):
        if b != 0.0:
            ns[f"b{m + 1}"] = b
            lines.append(f"    hb{m + 1} = h*b{m + 1}")
            bt.append((f"hb{m + 1}", m + 1))
    comps = [f"y{i} + " + _lin([(c, f"k{m}_{i}") for c, m in bt]) for i in range(n)]
    lines.append(f"    return ({', '.join(comps)},), ys{s}, {', '.join(f'k{j}' for j in range(2, s + 1))}")
    # error norm
    args = ", ".join(f"k{j}" for j in range(1, s + 2))
    err = ["def error_norm(y, y_new, " + args + ", h, rtol, atol):",
           f"    {', '.join(f'y{i}' for i in range(n))}, = y",
           f"    {', '.join(f'z{i}' for i in range(n))}, = y_new"]
    used = [m + 1 for m, e in enumerate(E) if e != 0.0]
    for m in used:
        ns[f"e{m}"] = E[m - 1]
        err.append(f"    he{m} = h*e{m}")
        err.append(f"    {', '.join(f'k{m}_{i}' for i in range(n))}, = k{m}")
    err.append("    acc = 0.0")
    for i in range(n):
        err.append(f"    d = ({_lin([(f'he{m}', f'k{m}_{i}') for m in used])}) / "
                   f"(atol + rtol*max(abs(y{i}), abs(z{i})))")
        err.append("    acc += d*d")
    err.append(f"    return (acc / {n}) ** 0.5")
    exec(compile("\n".join(lines) + "\n\n" + "\n".join(err) + "\n", f"<rk_kernels n={n} s={s}>", "exec"), ns)
    return ns["stages"], ns["error_norm"]
