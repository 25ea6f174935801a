"""Small test files for the calibration tests: specs, stitch-by-stitch and column CSVs."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

SBS_HEADER = ("run,frame,force_N,right_pin_x,right_pin_y,left_pin_x,left_pin_y,bottom_pin_x,"
              "bottom_pin_y,top_pin_x,top_pin_y,centre_x,centre_y")


def sbs_row(run: int, frame: int, force: float, gauge: float, width: float) -> str:
    """A tracking row with the pins placed for a given gauge length and width (pixels; image y
    grows downwards: the top pin has the smaller y)."""
    cx, cy = 200.0, 150.0
    return (f"{run},{frame},{force},{cx + width / 2},{cy},{cx - width / 2},{cy},{cx},"
            f"{cy + gauge / 2},{cx},{cy - gauge / 2},{cx},{cy}")


def write_sbs(path: Path, rows: list[str], clamp: float = 100.0, fabric: float = 150.0) -> Path:
    path.write_text("# A test fabric\n"
                    f"# clamp_size_px = {clamp}; fabric_width_px = {fabric}\n"
                    + SBS_HEADER + "\n" + "\n".join(rows) + "\n")
    return path


def write_columns(path: Path, force: np.ndarray, axial: np.ndarray,
                  lateral: np.ndarray | None = None, runs: np.ndarray | None = None) -> Path:
    cols = ["force_N", "axial_strain"] + (["lateral_strain"] if lateral is not None else []) + (
        ["run"] if runs is not None else [])
    lines = [",".join(cols)]
    for k in range(len(force)):
        cells = [f"{force[k]:.12g}", f"{axial[k]:.12g}"]
        if lateral is not None:
            cells.append(f"{lateral[k]:.12g}")
        if runs is not None:
            cells.append(str(runs[k]))
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_spec(folder: Path, text: str, name: str = "spec.toml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


def ramp_runs(path: Path, top: float = 30.0) -> Path:
    """A valid stitch-by-stitch file: two runs, force rising linearly to ``top``."""
    rows = []
    for run, stiff in ((1, 100.0), (2, 110.0)):
        for k in range(31):
            force = top * k / 30
            rows.append(sbs_row(run, k, force, 200.0 * (1 + force / stiff),
                                100.0 * (1 - 0.3 * force / stiff)))
    return write_sbs(path, rows)


SPEC_SBS = """\
    name = "tiny"
    [loop]
    length = 11.28
    [material]
    k_a = 0.5
    k_b = 0.02
    R_f = 0.045
    [units]
    length = "mm"
    force = "N"
    [calibrate]
    fit = ["k_b"]
    clamp_width_mm = 40.0
    min_loops = 2
    [[test]]
    file = "x.csv"
    format = "stitch_by_stitch"
    direction = "courses"
    use = "fit"
    """


SYNTH_DOC = {"loop": {"length": 11.28}, "units": {"length": "mm", "force": "N"}}
SYNTH_TRUTH = {"k_a": 0.01, "k_b": 0.001, "R_f": 0.045}


def synthetic_columns(path: Path, truth: dict[str, float] = SYNTH_TRUTH, courses: int = 2,
                      wales: int = 3, top: float = 10.0, noise: float = 0.002, runs: int = 3,
                      rows: int = 2000, seed: int = 1, strain: float = 0.4) -> float:
    """The model's own course-pull curve (``courses`` x ``wales``, ``truth``) written as a
    ``columns`` test of ``runs`` runs with Gaussian strain noise, forces up to ``top`` N; returns
    the specimen width (mm) that makes the model's force at axial ``strain`` equal ``top``."""
    from knit_nlp.weft.inverse.calibration.curve import SpecimenModel, strains_at
    from knit_nlp.weft.inverse.calibration.specimen import build_specimen
    sp = build_specimen({**SYNTH_DOC, "material": truth}, "<synthetic>", "courses", courses,
                        wales, "synthetic")
    c = SpecimenModel(sp).curve(truth, goal=1e9, strain_limit=strain)
    return noisy_columns(path, c, sp, top, noise, runs, rows, seed)


def noisy_columns(path: Path, c, sp, top: float, noise: float, runs: int, rows: int,
                  seed: int) -> float:
    """A model curve ``c`` of specimen ``sp`` written as a ``columns`` test of ``runs`` runs of
    ``rows`` rows with Gaussian strain noise (none at zero force), its forces scaled so that
    the curve's last force is ``top`` N; returns the specimen width (mm) of that scale."""
    from knit_nlp.weft.inverse.calibration.curve import strains_at
    forces = np.linspace(0.0, 0.99 * c.force[-1], rows)
    axial, lateral = strains_at(c, sp, forces)
    rng = np.random.default_rng(seed)
    cols: list[list[float]] = [[], [], [], []]
    for run in range(runs):
        da, dl = rng.normal(0, noise, rows), rng.normal(0, noise, rows)
        da[0] = dl[0] = 0.0
        cols[0] += list(forces * top / c.force[-1])
        cols[1] += list(axial + da)
        cols[2] += list(lateral + dl)
        cols[3] += [run + 1] * rows
    write_columns(path, *(np.array(col) for col in cols))
    return float(top / c.force[-1] * sp.pitch_width)


def synthetic_spec(folder: Path, width: float, fit: str, start: dict[str, float],
                   file: str = "synthetic.csv", extra: str = "", direction: str = "courses",
                   forces: str = "[2.0, 5.0, 8.0]", tables: str = "") -> Path:
    """The synthetic specimen's calibration spec (``tables``: more problem tables, e.g.
    ``[yarn]``; ``extra``: lines after the test)."""
    return write_spec(folder, f"""\
    name = "synthetic"
    [fabric]
    courses = 2
    wales = 3
    [loop]
    length = 11.28
    [material]
    k_a = {start['k_a']}
    k_b = {start['k_b']}
    R_f = {start['R_f']}
    [units]
    length = "mm"
    force = "N"
    {tables}
    [calibrate]
    fit = {fit}
    forces = {forces}
    [[test]]
    file = "{file}"
    format = "columns"
    direction = "{direction}"
    use = "fit"
    width = {width}
    {extra}""")


def predicted_wale_test(width: float, file: str = "synthetic.csv") -> str:
    """A second ``[[test]]`` for ``synthetic_spec``'s ``extra``: the same columns file as a wale
    pull that the calibration predicts (does not fit), on a specimen ``width`` mm wide."""
    return (f'[[test]]\nfile = "{file}"\nformat = "columns"\ndirection = "wales"\n'
            f'use = "predict"\nwidth = {width!r}\n')
