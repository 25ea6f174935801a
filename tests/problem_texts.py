"""TOML texts of the small problems several test files solve, each written once.

Most test problems begin alike: a fabric of m x n loops whose first loop's start is held at the
origin (``anchored``); what follows (more clamps, loads, tables) is each problem's own.
"""
from __future__ import annotations


def anchored(courses: int | str, wales: int | str, name: str | None = None) -> str:
    """``[fabric]`` of ``courses`` x ``wales`` loops (numbers, or ``{m}``-style fields left for
    ``str.format``) and the ``[[clamp]]`` holding loop (1, 1)'s start at the origin, after the
    top-level ``name`` when given. Keys of that clamp (``angle``, ``fix``) may follow."""
    head = f'name = "{name}"\n' if name is not None else ""
    return (f"{head}[fabric]\ncourses = {courses}\nwales = {wales}\n"
            '[[clamp]]\nloop = [1, 1]\npoint = "start"\nposition = [0.0, 0.0]\n')


def small_pull(name: str | None = None, displacement: str = "[1.0, 0.5]") -> str:
    """The 2 x 3 fabric ``anchored`` and pulled by loop (2, 3)'s point H, displaced by
    ``displacement`` (the command-line tests' smallest problem)."""
    return (anchored(2, 3, name)
            + f'[[clamp]]\nloop = [2, 3]\npoint = "H"\ndisplacement = {displacement}\n')


def bend(R_f: float | str = "{R_f}") -> str:
    """One course of three loops, its first loop's start clamped at angle 0, bent by a moment
    0.3 at its last loop's end, with bending modulus ``R_f`` (no crossing springs act)."""
    return (anchored(1, 3, "bend") + 'angle = 0.0\n[[load]]\nloop = [1, 3]\npoint = "end"\n'
            f"moment = 0.3\n[material]\nR_f = {R_f}\n")


def pull3d(name: str, L: float, R_f: float, radius: float, lift: float) -> dict:
    """A 2 x 2 fabric in 3-D (mm, N; ``[yarn] geometry = "3d"``, 4 elevation modes), loop
    (1, 1)'s start held and loop (1, 2)'s H lifted by ``lift`` mm along y, as a TOML table."""
    return {"name": name, "fabric": {"courses": 2, "wales": 2},
            "units": {"length": "mm", "force": "N"},
            "loop": {"length": L, "harmonics": 3}, "material": {"R_f": R_f},
            "yarn": {"radius": radius, "geometry": "3d", "elevation_modes": 4},
            "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                      {"loop": [1, 2], "point": "H", "displacement": [0.0, lift]}]}
