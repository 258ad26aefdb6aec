"""`vtrack synth OUT_DIR`: render a synthetic traffic video with exact ground truth."""

from __future__ import annotations

import argparse

from vtrack.sim.nuisance import NUISANCES

NAME = "synth"
SCENES = ("overhead", "mast", "side", "junction")
HELP = (
    "Render a synthetic traffic video with exact ground truth: OUT_DIR/video.avi (MJPG) and\n"
    "OUT_DIR/gt.csv (MOT rows frame,id,bb_left,bb_top,bb_width,bb_height,1,-1,-1,-1 plus the\n"
    "visible fraction 0..1; one row per frame in which a vehicle is at least partly inside\n"
    "the image, box clipped to the image). The same seed gives the same bytes of gt.csv.\n"
    "\n"
    "Scenes (--scene):\n"
    "  overhead  (default) a camera straight above a four-lane road; cars, vans and trucks\n"
    "            of one size across the frame; a footbridge and two trees hide them.\n"
    "  mast      a pole or bridge camera 8-30 m up looking down a straight road at 20-60\n"
    "            degrees: vehicles grow or shrink 4x and more, overlap along the line of\n"
    "            sight; traffic both ways; a sign gantry or a tree hides them.\n"
    "  side      a camera beside the road looking across it at a shallow angle: near lanes\n"
    "            hide far ones; many articulated trucks.\n"
    "  junction  a corner pole over a signalised crossing: queues stand at red, then drive\n"
    "            off; vehicles turn.\n"
    "mast, side and junction also write OUT_DIR/world.csv (frame,id,X_m,Y_m,speed_kmh,\n"
    "length_m,class: the centre of each vehicle's footprint on the road plane) and\n"
    "OUT_DIR/calibration.toml (road-plane points with their pixels, for vtrack track\n"
    "--calibration). Camera, road, lanes, colours, sizes, sun and traffic come from the seed.\n"
    "\n"
    "Nuisances (--nuisance all|none|NAME,NAME...; default all for mast/side/junction,\n"
    "none for overhead, which has none):\n"
    + "".join(f"  {name:<11} {text}\n" for name, text in NUISANCES.items())
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare OUT_DIR and the scene options (defaults shown in --help)."""
    parser.add_argument("out_dir", metavar="OUT_DIR", help="output folder (created if needed)")
    parser.add_argument("--scene", choices=SCENES, default="overhead",
                        help="camera and road (default overhead)")
    parser.add_argument("--frames", type=int, default=300, help="number of frames (default 300)")
    parser.add_argument("--vehicles", type=int, default=None,
                        help="vehicles scheduled to enter during the clip (default 12 for "
                             "overhead, drawn from the seed for the other scenes; in dense "
                             "traffic the last ones may still queue at the end)")
    parser.add_argument("--width", type=int, default=640, help="frame width (default 640)")
    parser.add_argument("--height", type=int, default=360, help="frame height (default 360)")
    parser.add_argument("--fps", type=float, default=25.0, help="frame rate (default 25)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--quality", type=int, default=None,
                        help="MJPG quality 1..100 (default 90; with the compression nuisance "
                             "drawn from the seed in 30..70)")
    parser.add_argument("--nuisance", default=None, metavar="LIST",
                        help="all, none or a comma list of the nuisances above (default all "
                             "for mast/side/junction, none for overhead)")


def run(args: argparse.Namespace) -> int:
    """Render and report what was written."""
    from vtrack.errors import InputError
    from vtrack.sim.nuisance import parse_nuisances

    default = "none" if args.scene == "overhead" else "all"
    nuisances = parse_nuisances(default if args.nuisance is None else args.nuisance)
    if args.scene == "overhead":
        if nuisances:
            raise InputError("--nuisance: the overhead scene has no nuisances (use --scene "
                             "mast, side or junction)")
        from vtrack.sim.traffic import render_scene

        res = render_scene(args.out_dir, frames=args.frames,
                           vehicles=12 if args.vehicles is None else args.vehicles,
                           width=args.width, height=args.height, fps=args.fps, seed=args.seed,
                           quality=90 if args.quality is None else args.quality)
        print(f"wrote {res.video} ({res.frames} frames, {res.width}x{res.height}) and {res.gt} "
              f"({res.vehicles} vehicles, {res.gt_rows} rows) in {res.seconds:.1f} s")
        return 0
    from vtrack.sim.clip import render_preset

    res = render_preset(args.out_dir, args.scene, frames=args.frames, vehicles=args.vehicles,
                        width=args.width, height=args.height, fps=args.fps, seed=args.seed,
                        quality=args.quality, nuisances=nuisances)
    print(f"wrote {res.video} ({res.frames} frames, {res.width}x{res.height}, MJPG quality "
          f"{res.quality}), {res.gt} ({res.vehicles} vehicles, {res.gt_rows} rows), "
          f"{res.world} and {res.calibration} in {res.seconds:.1f} s")
    return 0
