"""Entry points behind ``knit-nlp control``, ``knit-nlp fit`` and ``knit-nlp overlay``."""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import matplotlib.image as mpimg
import numpy as np
from PIL import Image

from ...errors import ArgumentError, ProblemError, quoted, shown
from ...jsonio import write_json
from ...outdir import output_name, prepare_out
from ...progress import end_lines
from ...problems import resolve
from ...tomlio import load_toml, read_regular_file
from ..model.params import MATERIAL
from ..model.problem import WeftProblem, parse_problem
from .control import control, control_summary
from .fit import fit, fit_name
from .observations import load_observations
from .overlay import check_shape, load_result, overlay, parse_match, point_reader
from .spec import note_ignored_reduction, parse_control, strip_control_keys

MAX_IMAGE_BYTES = 64 * 2 ** 20     # a photograph for overlay (docs/limits.md)
MAX_IMAGE_PIXELS = 25_000_000      # ... and its pixels, from its header (a 24 MP camera's)


def control_file(path: Path, doc: dict[str, Any], out: Path) -> int:
    """``knit-nlp control``: check the output folder, solve, write ``<problem>.control.json``
    and ``.png`` and print readable lines (``control_summary``); exit 0 only for a converged,
    stable, forward-checked answer."""
    cp = parse_control(path, doc)
    prepare_out(str(out), cp.problem.name, ("control",))
    note_ignored_reduction(path, cp.problem, "control")
    ans = control(cp)
    paths = ans.save(out)
    end_lines()
    print(control_summary(ans, paths))
    return 0 if ans.success else 1


def fit_files(paths: list[Path], observations: Path, params: list[str], out: Path,
              name: str | None = None) -> int:
    """``knit-nlp fit``: write ``<name>.fit.json`` and ``.fit.png`` (``name``: ``--name``, by
    default the load cases' names joined by "+", ``fit.fit_name``); exit 0 when the fit
    converged."""
    check_params(params)
    if name is not None:
        output_name("--name", name)
    problems = {}
    for path in paths:
        pr = parse_problem(strip_control_keys(load_toml(path)), path)
        if pr.name in problems:
            raise ProblemError(path, "", "name", f"two load cases are named {pr.name!r}")
        problems[pr.name] = pr
    obs = load_observations(observations, problems)
    missing = sorted(set(problems) - {o.case for o in obs})
    if missing:
        raise ProblemError(observations, "", "case", f"no observations of case {missing[0]!r}")
    _check_fittable(paths[0], next(iter(problems.values())), params)
    name = fit_name(list(problems)) if name is None else name
    prepare_out(str(out), name, ("fit",))
    for path, pr in zip(paths, problems.values()):      # after every refusal: one line on exit 2
        note_ignored_reduction(path, pr, "fit")
    ans = fit(list(problems.values()), obs, params)
    ans.files = {case: str(path) for case, path in zip(problems, paths)}
    ans.name = name
    js, png = ans.save(out)
    result = ans.to_json()
    end_lines()
    print(f"fit: {result['status']} in {result['iterations']} iterations, "
          f"{result['n_observations']} observed points, rms residual {result['rms_residual']:.4g}")
    for name, v in result["parameters"].items():
        se = "undetermined" if v["std_error"] is None else f"± {v['std_error']:.3g}"
        print(f"  {name} = {v['value']:.6g} {se} (initial {v['initial']:.4g})")
    for case, told in result["check"].items():       # each case's equilibrium, checked
        print(f"  check of {case}: {told['verdict']}")
    for w in result["warnings"]:
        print(f"  warning: {w}")
    print(f"  wrote {js}, {png}")
    return 0 if ans.success else 1


def check_params(params: list[str]) -> None:
    """``fit --params``: at least one material value (:data:`MATERIAL`), each at most once;
    else an :class:`ArgumentError` naming the name and the allowed ones."""
    allowed = ", ".join(MATERIAL)
    if not params:
        raise ArgumentError("--params", f"give at least one of {allowed}")
    for k, name in enumerate(params):
        if name not in MATERIAL:
            raise ArgumentError(f"--params {shown(name)}", f"unknown parameter {quoted(name)}; "
                                f"use {allowed}")
        if name in params[:k]:
            raise ArgumentError(f"--params {shown(name)}", f"given twice; give each of "
                                f"{allowed} at most once")


def _check_fittable(path: Path, first: WeftProblem, params: list[str]) -> None:
    """The fit starts from the first load case's values and works on their logarithms: each
    value fitted must be positive (a zero has no logarithm and no scale)."""
    for param in params:
        if not getattr(first, param) > 0:
            raise ProblemError(path, "material", param, f"is {getattr(first, param)!r}; a fit "
                               f"works on log {param}, so its start value must be positive: "
                               f"set a positive guess or leave {param} out of --params")


def overlay_file(result_path: Path, image: Path, matches: list[str], observations: Path | None,
                 problem: Path | None, out: Path) -> int:
    """``knit-nlp overlay``: read and check everything, then write (``OverlayAnswer.save``)
    ``<result stem>.<image stem>.overlay.json`` and ``.overlay.png`` (``overlay_name``)."""
    shape = load_result(result_path)
    problem = problem or _problem_of(shape.result, result_path)
    reader, pr = point_reader(problem)
    check_shape(shape, pr, result_path, problem)
    parsed = [parse_match(m, reader) for m in matches]
    obs = None
    if observations is not None:
        obs = load_observations(observations, {pr.name: pr}, other_cases=True)
    picture = read_image(image)
    ans = overlay(shape, parsed, obs, result_path=result_path, image=image,
                  picture=picture)                  # refused matches: nothing written
    prepare_out(str(out), ans.name, ("overlay",))
    js, png = ans.save(out)
    t = ans.transform
    print(f"similarity: scale {t.scale:.6g} px/unit, rotation {np.degrees(t.rotation):.4f} deg, "
          f"shift ({t.b.real:.3f}, {-t.b.imag:.3f}) px")
    for m, r in zip(parsed, ans.residuals_px):
        print(f"  match {list(m.loop)} {m.point} -> {m.pixel.tolist()}: residual {r:.3f} px")
    if ans.observed_rms is not None:
        print(f"  observed vs computed: RMS {ans.observed_rms:.4g} model units over {len(obs)} points")
    print(f"  wrote {png}, {js}")
    return 0


def read_image(image: Path) -> np.ndarray:
    """The photograph's pixels: a regular file of at most ``MAX_IMAGE_BYTES`` whose header
    declares at most ``MAX_IMAGE_PIXELS`` pixels, checked before it is decoded (a PNG of a few
    kB can declare 60000 x 60000 pixels and take tens of GB to decode and draw)."""
    data = read_regular_file(image, MAX_IMAGE_BYTES)
    try:
        width, height = _declared_size(data)
        if width * height > MAX_IMAGE_PIXELS:
            raise ProblemError(image, "", "", f"{width} x {height} pixels; the limit is "
                               f"{MAX_IMAGE_PIXELS} pixels: scale the photograph down")
        return mpimg.imread(io.BytesIO(data))
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as err:
        raise ProblemError(image, "", "", f"cannot read the image ({err})") from None


def _declared_size(data: bytes) -> tuple[int, int]:
    """(width, height) from an image's header, without decoding it (Pillow's own bomb check,
    which refuses only images above 179 megapixels without saying their size, set aside)."""
    limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
    try:
        with Image.open(io.BytesIO(data)) as im:
            return im.size
    finally:
        Image.MAX_IMAGE_PIXELS = limit


def _problem_of(result: dict, result_path: Path) -> Path:
    """The problem file a result came from, to resolve point labels: its recorded ``source``,
    else a file named after the problem beside the result or among the named problems."""
    name = str(result.get("problem", ""))
    source = result.get("source")
    recorded = Path(source["file"]) if isinstance(source, dict) and isinstance(source.get("file"), str) else None
    for candidate in (recorded, result_path.parent / f"{name}.toml"):
        if candidate is not None and candidate.is_file():
            return candidate
    try:
        return resolve(name)
    except ProblemError:
        raise ProblemError(result_path, "", "problem", f"cannot find the problem file {name!r} "
                           "to resolve point labels; pass --problem FILE") from None
