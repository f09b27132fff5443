"""``mfcl simulate``: a dataset folder written by simulating a LiDAR walk through a floor
plan (``mfcl_jax.sources.simulated``)."""

from __future__ import annotations

from pathlib import Path

from mfcl_jax.cli.progress_flag import add_progress_flag

__all__ = ["add_simulate_command", "cmd_simulate"]


def add_simulate_command(subparsers) -> None:
    """Adds ``simulate`` to an argparse sub-parser set."""
    si = subparsers.add_parser(
        "simulate", help="write a dataset folder by simulating a LiDAR walk through a floor plan"
    )
    si.add_argument("--floorplan", type=Path, required=True, help=".ifc, .geojson or .yaml")
    si.add_argument("--trajectory", type=Path, required=True, help="waypoints CSV: x,y per line")
    si.add_argument("--out", type=Path, required=True, help="dataset folder to create")
    si.add_argument("--seed", type=int, default=0, help="noise and drift seed (0)")
    si.add_argument("--storey", help="IFC storey name or elevation")
    si.add_argument("--odom-rate", type=float, metavar="HZ",
                    help="write odometry.tum at this rate with its own stamps, as wheel "
                    "odometry or an LIO publishes it (default: one pose per scan)")  # fmt: skip
    si.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    add_progress_flag(si)
    si.set_defaults(func=cmd_simulate)


def cmd_simulate(args) -> int:
    from mfcl_jax.floorplan.load import floorplan_files, load_floorplan
    from mfcl_jax.io import DataError, check_output
    from mfcl_jax.robot.progress import COMPILING, Progress

    progress = Progress(True if args.progress else None)
    if args.odom_rate is not None and not args.odom_rate > 0:
        raise DataError(f"--odom-rate: must be a positive rate in Hz, got {args.odom_rate}")
    if args.out.exists() and not args.overwrite:
        raise DataError(f"{args.out}: already exists (pass --overwrite to replace it)")
    inputs = [args.trajectory, *floorplan_files(args.floorplan)]
    check_output(args.out, inputs=inputs, folder=True)
    with progress.stage("starting (loading JAX)"):
        from mfcl_jax.robot.compile_cache import enable_cache
        from mfcl_jax.sources.simulated import simulate_dataset
        from mfcl_jax.sources.walks import read_waypoints

        enable_cache()
    wp = read_waypoints(args.trajectory)
    with progress.stage(f"loading {args.floorplan}"):
        fp = load_floorplan(args.floorplan, storey=args.storey)
    if fp.storeys is not None:
        from mfcl_jax.io import DataError

        raise DataError(
            f"{args.floorplan}: {len(fp.storeys.names)} storeys "
            f"({', '.join(map(repr, fp.storeys.names))}): a walk is on one; pass --storey NAME"
        )
    with progress.stage(f"simulating the walk and writing {args.out} (ray caster: {COMPILING})"):
        out = simulate_dataset(
            fp, wp, args.out, seed=args.seed, overwrite=args.overwrite,
            where=str(args.trajectory), odom_rate=args.odom_rate,
        )  # fmt: skip
    from mfcl_jax.io import read_tum

    t, _ = read_tum(out / "odometry.tum")
    n_scans = len(list((out / "scans").glob("*.pcd")))
    rate = f", odometry at {args.odom_rate:g} Hz ({len(t)} poses)" if args.odom_rate else ""
    print(f"{out}: {n_scans} scans over {t[-1] - t[0]:.1f} s in {fp.name} (seed {args.seed}){rate}")
    return 0
