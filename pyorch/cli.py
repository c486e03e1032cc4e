"""Command line: ``pyorch run|check|plot``.

    pyorch run SCENE.nml [--out DIR] [--overwrite] [--set group.key=value ...] [--door exe|f2py]
               [--no-plots]
    pyorch run SCENE.nml --start-from FILE.gsd[:FRAME] [--type-map A=1,B=2] [...]
    pyorch run --resume RUN_DIR
    pyorch check SCENE.nml [--set ...]
    pyorch scene describe KIND | start-file SCENE.nml FILE.gsd[:FRAME] [-o OUT]
    pyorch plot RUN_DIR [--out DIR] [--no-structure]
    pyorch analyze RUN_DIR [--out DIR]
    pyorch bench trade|bias|seeds [--scene S] [--seeds N] [--quick] [--workers W]
                 [--out DIR | --update-shipped]
    pyorch bench trade --kind lj_box|rods|dla|oscillator [--seeds N] [--quick] [--out DIR | --update-shipped]
    pyorch sweep SWEEP.toml [--workers N] [--scheduler ADDR] [--cluster local|slurm]
    pyorch dataset gns SPEC.toml [--workers N] [--scheduler ADDR] [--dry-run]
    pyorch dataset check DATASET_DIR
    pyorch export RUN_DIR --format gsd|xyz [-o FILE] [--double]
    pyorch movie RUN_DIR [--fps F] [--every K] [--color-by C] [--out FILE.mp4|.gif]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pyorch import RunError, SceneError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="pyorch", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)

    r = sub.add_parser("run", help="run a scene (namelist) into a run directory")
    r.add_argument("scene", type=Path, nargs="?", help="scene namelist (omit with --resume)")
    r.add_argument("--resume", type=Path, default=None, metavar="RUN_DIR",
                   help="continue RUN_DIR from its last checkpoint")
    r.add_argument("--out", type=str, default=None, help="run directory (default runs/out/<scene>)")
    r.add_argument("--overwrite", action="store_true",
                   help="replace a run found in the run directory (its files are removed first)")
    set_help = ("override one key: group.key=value (namelist value; string keys take bare "
                "text; arrays: key(i)=v or 1.0,0.6 or [1.0,0.6]); repeatable. "
                "'pyorch scene describe KIND' lists the keys")
    r.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="GROUP.KEY=VALUE", help=set_help)
    r.add_argument("--start-from", default=None, metavar="FILE.gsd[:FRAME]",
                   help="start from frame FRAME of a GSD file (default the last): converted "
                        "into RUN_DIR/start.txt, which the run's &particles start_file names")
    from pyorch.start import add_scene_parser, add_type_map

    add_type_map(r)
    r.add_argument("--door", choices=["exe", "f2py"], default="exe")
    r.add_argument("--no-plots", action="store_true")
    r.add_argument("--quiet", action="store_true", help="no progress bar")

    c = sub.add_parser("check", help="validate a scene through the engine")
    c.add_argument("scene", type=Path)
    c.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="GROUP.KEY=VALUE", help=set_help)

    sc = sub.add_parser("scene", help="a kind's scene keys: every group and key with its type, "
                                      "default, allowed values, unit and meaning")
    sc_sub = sc.add_subparsers(dest="scene_cmd", required=True)
    de = sc_sub.add_parser("describe", help="print the table of a kind's keys (Markdown)")
    de.add_argument("kind", help="scene kind: magnet_bed, oscillator, dla, rods, lj_box")
    de.add_argument("--json", action="store_true", help="the declaration as JSON")
    add_scene_parser(sc_sub, set_help)

    pl = sub.add_parser("plot", help="write the standard figures of a run directory")
    pl.add_argument("run_dir", type=Path)
    pl.add_argument("--out", type=Path, default=None)
    pl.add_argument("--no-structure", action="store_true",
                    help="bed: skip the Voronoi/force figures of pyorch.bed.analyze.plot_run")

    an = sub.add_parser("analyze", help="structure/force tables of a run directory as CSV")
    an.add_argument("run_dir", type=Path)
    an.add_argument("--out", type=Path, default=None, help="default RUN_DIR/analysis")

    from pyorch.sweep import add_parser as add_sweep_parser

    add_sweep_parser(sub)

    import importlib

    from pyorch.kinds import KINDS

    for kind in KINDS.values():                 # a kind's own commands (e.g. lj_box: dataset)
        for module in kind.commands:
            importlib.import_module(module).add_parser(sub)

    from pyorch.export import add_parser as add_export_parser
    from pyorch.movie import add_parser as add_movie_parser

    add_export_parser(sub)
    add_movie_parser(sub)

    b = sub.add_parser("bench", help="speed/accuracy trade study or truncation bias study")
    b.add_argument("what", choices=["trade", "bias", "seeds"],
                   help="trade: every knob; bias: bias vs r_c; seeds: seed-averaged bias of "
                        "the production settings with standard errors")
    b.add_argument("--scene", type=Path, default=None,
                   help="the bed's study scene (default runs/bench_compression.nml)")
    b.add_argument("--kind", default=None,
                   help="trade: the kind's own studies (lj_box, rods, dla, oscillator; default "
                        "the bed's), each on its own scene (--scene, --workers and --reuse are "
                        "the bed's: refused with --kind)")
    b.add_argument("--seeds", type=int, default=None,
                   help="seeds per setting (default 3 for the bed, the study's own for a kind)")
    b.add_argument("--quick", action="store_true", help="4 settings only (smoke test)")
    b.add_argument("--workers", type=int, default=None,
                   help="engine processes at once (errors only: times are then contended)")
    b.add_argument("--reuse", type=Path, default=None,
                   help="rows CSV of an earlier study of the scene: completed runs are kept")
    b.add_argument("--out", type=Path, default=None,
                   help="where the tables, figures and runs go (default runs/out/bench)")
    b.add_argument("--update-shipped", action="store_true",
                   help="write the shipped tables in bench/results (target_rel_error chooses "
                        "from them; not with --quick)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 ok, 2 bad input, then the engine's own (3 numerical guard,
    4 I/O or refused run directory/checkpoint, 5 interrupted with a
    checkpoint), 1 internal, 130 Ctrl-C outside a run."""
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:
        print("pyorch: interrupted", file=sys.stderr)
        return 130


def _main(args: argparse.Namespace) -> int:
    try:
        if args.cmd == "run":
            return _cmd_run(args)
        if args.cmd == "check":
            return _cmd_check(args)
        if args.cmd == "scene" and args.scene_cmd == "start-file":
            from pyorch.start import cmd_start_file

            return cmd_start_file(args)
        if args.cmd == "scene":
            import json

            from pyorch.scene import describe, schema

            if args.json:
                print(json.dumps(schema(args.kind), indent=1))
            else:
                print(describe(args.kind), end="")
            return 0
        if args.cmd == "sweep":
            from pyorch.sweep import cmd_sweep

            return cmd_sweep(args)
        if getattr(args, "func", None) is not None:   # a kind's command (Kind.commands)
            return int(args.func(args))
        if args.cmd == "export":
            from pyorch.export import cmd_export

            return cmd_export(args)
        if args.cmd == "movie":
            from pyorch.movie import cmd_movie

            return cmd_movie(args)
        if args.cmd == "bench":
            from pyorch.bench import main_bench

            return main_bench(args)
        if args.cmd == "plot":
            from pyorch import kinds

            plugin = kinds.plugin(kinds.of_run(args.run_dir))
            for p in plugin.save_run_plots(args.run_dir, args.out, full=not args.no_structure):
                print(p)
            return 0
        if args.cmd == "analyze":
            from pyorch import kinds

            plugin = kinds.plugin(kinds.of_run(args.run_dir))
            for p in plugin.write_tables(args.run_dir, args.out):
                print(p)
            return 0
    except SceneError as exc:
        print(f"pyorch: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"pyorch: error: {exc}", file=sys.stderr)
        return exc.code
    return 1


def _cmd_check(args: argparse.Namespace) -> int:
    """Validate through the engine; with ``target_rel_error`` also the setting it would
    choose (as ``pyorch run`` does) and, where the kind estimates one, the run time at it."""
    from pyorch import trade
    from pyorch.scene import Scene, validate

    scene = Scene.read(args.scene)  # the engine's reading: SceneError if refused
    if args.overrides:
        scene = scene.with_overrides(args.overrides)
    tuned, choice = trade.apply_target(scene)
    # the user's file as it is unless pyorch changes it (then pyorch writes it again)
    info = validate(tuned if args.overrides or choice else args.scene)
    extra = f"{info['n_particles']} particles, " if "n_particles" in info else ""
    print(f"ok: {info['kind']}, {extra}{info['n_steps']} steps")
    if choice is not None:
        print(choice)
        for line in trade.check_lines(scene, info):
            print(line)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from pyorch.run import run
    from pyorch.scene import Scene

    from pyorch.run import resume
    from pyorch.trade import apply_target

    if args.resume is not None:
        if args.scene is not None or args.overrides or args.out is not None or args.overwrite \
                or args.start_from is not None:
            raise SceneError("--resume RUN_DIR continues a run as it was: no scene, --set, "
                             "--out, --overwrite or --start-from")
        result = resume(args.resume, door=args.door, progress=not args.quiet)
        out = args.resume
        meta = result.meta
        print(f"{out}: {meta['status']}, {meta['steps_done']} steps")
        if not args.no_plots:
            from pyorch import kinds

            kinds.plugin(kinds.of_run(out)).save_run_plots(out)
        return 0
    if args.scene is None:
        raise SceneError("pyorch run: give a scene file (or --resume RUN_DIR)")
    if args.out is not None and not args.out.strip():
        raise SceneError("pyorch run: --out needs a non-empty directory name")
    scene = Scene.read(args.scene)
    tuned, choice = apply_target(scene.with_overrides(args.overrides))
    if choice:
        print(choice)
    out = Path(args.out) if args.out is not None else Path("runs") / "out" / args.scene.stem
    if args.start_from is not None:
        from pyorch.start import parse_type_map, run_from_gsd

        result = run_from_gsd(tuned, args.start_from, out, parse_type_map(args.type_map),
                              overwrite=args.overwrite, door=args.door, progress=not args.quiet)
    elif args.overrides or choice:
        result = run(tuned, out, door=args.door, progress=not args.quiet, overwrite=args.overwrite)
    else:  # the user's file as it is: the engine reads it and names it in any message
        result = run(args.scene, out, door=args.door, progress=not args.quiet,
                     overwrite=args.overwrite)
    meta = result.meta
    print(f"{out}: {meta['status']}, {meta['steps_done']} steps, "
          f"{meta['wall_time_s']:.2f} s ({1e6 * meta['wall_time_per_step_s']:.1f} us/step)")
    if not args.no_plots:
        from pyorch import kinds

        paths = kinds.plugin(kinds.of_run(out)).save_run_plots(out)
        print(f"{len(paths)} plots in {out / 'plots'}")
    return 0
