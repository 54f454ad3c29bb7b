"""``pipeline validate``: the paper's validation (Table 1, Figs. 2–5) on the configured engine,
and the contact statics against the elastica (:mod:`pipeline.reports.contact_statics`).

Each figure is a :class:`~pipeline.reports.checks.Section` built by its module
(resonance_checks, collision_checks, follicle_check, array_checks); this module runs them in
order, reports progress, and writes report.md, one PNG per section and validation.json (every
check with the published value beside ours, and the numbers behind every figure).

``quick`` keeps every section but with fewer whiskers and speeds and no engine runs for Fig. 2
(well under a minute on Bullet); the full run takes a few minutes. The sections run in up to
two processes.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Callable

from pipeline.config.physics import ModelConfig
from pipeline.errors import UserError
from pipeline.protocols.collision import SPEEDS_DEG_S
from pipeline.reports.array_checks import array_section
from pipeline.reports.checks import Section
from pipeline.reports.collision_checks import collision_runs, front_section, shock_section
from pipeline.reports.contact_statics import contact_statics_section
from pipeline.reports.document import Markdown, number, write_json
from pipeline.reports.follicle_check import follicle_section
from pipeline.reports.resonance_checks import array_resonance, engine_resonances, table_1
from pipeline.reports.validation_figures import write_figure

QUICK_COLLISION_WHISKERS = ("RA0",)
FULL_COLLISION_WHISKERS = ("RA0", "RB1", "RC2", "RD0")
QUICK_SPEEDS_DEG_S = (90, 270, 540)
SECTIONS = ("table1", "fig2", "fig3_shock", "fig3_front", "fig4", "fig5", "contact_statics")
# Longest first, so that two processes finish together (seconds on Bullet, full run).
LONGEST_FIRST = ("contact_statics", "fig5", "fig3_shock", "fig2", "table1", "fig4", "fig3_front")


def build_section(name: str, config: ModelConfig, quick: bool, mesh: Path | None,
                  progress: Callable[[str], None] | None = None) -> tuple[Section, float]:
    """(section ``name``, seconds it took) with the material of ``config`` (Table 1 not refitted)."""
    progress = progress or (lambda _: None)
    begin = time.perf_counter()
    if name == "table1":
        section = table_1(config, False, progress)[0]
    elif name == "fig2":
        section = array_resonance(config, [] if quick else engine_resonances(config, progress=progress))
    elif name == "fig3_shock":
        whiskers = QUICK_COLLISION_WHISKERS if quick else FULL_COLLISION_WHISKERS
        speeds = QUICK_SPEEDS_DEG_S if quick else SPEEDS_DEG_S
        section = shock_section(collision_runs(config, whiskers, speeds, progress))
    elif name == "fig3_front":
        section = front_section(config, progress)
    elif name == "fig4":
        section = follicle_section(config, progress)
    elif name == "fig5":
        section = array_section(config, quick, mesh, progress)
    elif name == "contact_statics":
        section = contact_statics_section(config, quick, progress)
    else:
        raise ValueError(f"unknown validation section {name}")
    return section, time.perf_counter() - begin


def validate(model: ModelConfig, out: str | Path, quick: bool = False, refit: bool = False,
             mesh: str | Path | None = None, progress: Callable[[str], None] = lambda _: None,
             workers: int | None = None) -> dict:
    """Run every section and write the report into ``out``; returns the checks and the paths.

    The sections are independent simulations: with ``workers`` > 1 (default: up to 2, one per
    core) they run in that many processes, longest first, and progress reports each section as
    it finishes. ``refit`` first refits the material on Table 1 (in this process); the other
    sections then use the refitted material.
    """
    start = time.perf_counter()
    mesh = Path(mesh) if mesh else None
    if mesh is not None and not mesh.is_file():
        raise UserError(f"--mesh {mesh}: no such file")
    workers = min(2, os.cpu_count() or 1) if workers is None else workers
    done: dict[str, tuple[Section, float]] = {}
    config = model
    if refit:
        begin = time.perf_counter()
        section, config = table_1(model, True, progress)
        done["table1"] = (section, time.perf_counter() - begin)
    names = [n for n in LONGEST_FIRST if n not in done]
    if workers <= 1:
        for name in SECTIONS:
            if name in names:
                done[name] = build_section(name, config, quick, mesh, progress)
    else:
        progress(f"{', '.join(names)}: running in {workers} processes ({config.engine.name})")
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {pool.submit(build_section, name, config, quick, mesh): name for name in names}
            for future in as_completed(futures):
                done[futures[future]] = future.result()
                progress(f"{futures[future]} done ({done[futures[future]][1]:.0f} s)")
    sections = [done[name][0] for name in SECTIONS]
    meta = {"engine": config.engine.name, "quick": quick, "refit": refit, "seconds": time.perf_counter() - start,
            "section_seconds": {name: done[name][1] for name in SECTIONS}, "workers": workers}
    progress("writing the report")
    result = write_validation_report(sections, config, out, meta)
    return {**result, "seconds": time.perf_counter() - start}


def write_validation_report(sections: list[Section], config: ModelConfig, out: str | Path, meta: dict) -> dict:
    """report.md, ``<section>.png`` and validation.json in ``out``; returns the checks and paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    figures = {s.name: write_figure(s, out) for s in sections}
    checks = [(s, c) for s in sections for c in s.checks]
    judged = [c for _, c in checks if c.agrees is not None]
    agree = sum(bool(c.agrees) for c in judged)
    material = config.material
    doc = Markdown("Validation against the WHISKiT Physics paper")
    doc.paragraph(
        f"Engine {config.engine.name} (step {config.engine.dt_s:g} s, f1 tolerance {config.engine.f1_tolerance:g}), "
        f"{material.links} links, E = {material.youngs_modulus_gpa:.3g} GPa, θ_ζ = {material.damping_ratio:.3g} "
        f"({material.damping_model} damping{', refitted on Table 1' if meta.get('refit') else ''}), follicle "
        f"{material.follicle.kind}. {'Quick run (fewer whiskers and speeds). ' if meta.get('quick') else ''}"
        f"{number(meta.get('seconds'))} s. Every number is in `validation.json`.")
    doc.heading("Summary")
    doc.paragraph(f"{agree} of {len(judged)} judged checks agree with the published values "
                  f"({len(checks) - len(judged)} reported without a verdict).")
    doc.table(["section", "check", "published", "ours", "agrees", "criterion"],
              [[s.name, c.label, number(c.published) + (f" ± {number(c.published_sd)}" if c.published_sd else ""),
                c.ours(), {True: "yes", False: "**no**", None: "–"}[c.agrees], c.criterion]
               for s, c in checks])
    for section in sections:
        doc.heading(section.title)
        if figures[section.name] is not None:
            doc.image(section.name, figures[section.name].name)
        doc.paragraph(section.full_caption())
    report = doc.write(out / "report.md")
    check_dicts = [c.as_dict() for _, c in checks]
    data = {**meta, "config": config.model_dump(mode="json"), "agree": agree, "judged": len(judged),
            "checks": check_dicts, "sections": {s.name: s.summary for s in sections}}
    json_path = write_json(out / "validation.json", data)
    return {"checks": check_dicts, "agree": agree, "judged": len(judged), "seconds": meta.get("seconds", 0.0),
            "report": str(report), "json": str(json_path),
            "figures": [str(p) for p in figures.values() if p is not None]}
