"""``rig cam-design [SCENE]``: the cam-design checks of a cam-bar scene (or a course-lab cam) against their limits,
and a chart.

Kept outside :mod:`rig.mechanisms` so that ``rig --help`` does not import numpy; the work happens in
:mod:`rig.mechanisms.cam.design`.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

DEFAULT_SCENE = Path(__file__).resolve().parents[1] / "data" / "scenes" / "pin_insertion.toml"


def cmd_cam_design(args: argparse.Namespace) -> int:
    from rig.cam_design_chart import plot_design
    from rig.mechanisms.cam.design import design_checks, format_checks
    from rig.outputs import PNG_MAGIC, file_parent, writable_file
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_speed_profile, require_cam_bar
    from rig.scene import load_scene
    output = Path(args.output) if args.output else Path("out") / f"{Path(args.scene).stem}.cam_design.png"
    writable_file(output, "cam-design chart", PNG_MAGIC)
    if args.sigma_allow is not None and not (math.isfinite(args.sigma_allow) and args.sigma_allow > 0):
        raise ValueError(f"--sigma-allow must be a positive permissible Hertz stress in MPa, got {args.sigma_allow}")
    options = {} if args.sigma_allow is None else {"sigma_allow": args.sigma_allow * 1e6}
    if args.load_coefficient is not None:
        options["load_coefficient"] = args.load_coefficient
    scene = load_scene(args.scene)
    if scene.section("scene").get("plant") == "lab_bench" and scene.section("plant").get("kind") == "cam":
        if args.low_speed:
            raise ValueError("--low-speed picks the oscillating follower's 45° limit; a lab cam's translating follower "
                             "has one limit, 30°")
        design = _lab_cam_design(scene, options)
    else:
        require_cam_bar(scene, "rig cam-design", 'or a lab_bench scene of kind "cam" (lab_cam.toml)')
        mech, omega = mechanism_from_scene(scene), read_speed_profile(scene).nominal_omega
        design = design_checks(mech, omega, high_speed=not args.low_speed, **options)
    print(f"cam design checks for {args.scene}")
    print(format_checks(design))
    print(f"chart: {plot_design(design, file_parent(output), Path(args.scene).name)}")
    return 0 if all(c.ok for c in design.checks) else 1


def _lab_cam_design(scene, options: dict):
    """The checks of a course-lab cam (a centric translating roller follower, ``rig.mechanisms.cam.translating``)."""
    from rig.mechanisms.cam.translating import translating_design
    from rig.plants.lab_bench import SCHEMAS, LabBench
    if "sigma_allow" in options:
        raise ValueError("--sigma-allow needs a roller width for the Hertz stress; a lab cam scene gives none")
    bench = LabBench.from_scene(scene)
    plant = scene.read("plant", SCHEMAS["cam"])
    omega = bench.speed.nominal_omega
    return translating_design(bench.mechanism, omega, lambda phi: bench.cam_contact_force(phi, omega),
                              plant["base_radius"], plant["roller_radius"], **options)


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``rig cam-design`` to the ``rig`` parser."""
    p = sub.add_parser("cam-design", parents=parents,
                       help="cam checks (pressure angle, undercut, Hertz, sizing, cusps, synthesis) and chart")
    p.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE),
                   help="cam-bar scene, or a lab_bench scene of kind \"cam\" (default data/scenes/pin_insertion.toml)")
    p.add_argument("--low-speed", action="store_true",
                   help="oscillating follower at low speed: pressure-angle limit 45° instead of 30°")
    p.add_argument("--sigma-allow", type=float, metavar="MPA",
                   help="permissible Hertz stress (MPa; default 1200, an assumption for hardened steel)")
    p.add_argument("--load-coefficient", type=float, metavar="Q/F",
                   help="load coefficient Φ_L of the H/h optimum (default 0.5, an assumption)")
    p.add_argument("-o", "--output", help="chart PNG (default out/<scene file name>.cam_design.png, e.g. "
                                            "out/pin_insertion.cam_design.png)")
    p.set_defaults(func=cmd_cam_design)
