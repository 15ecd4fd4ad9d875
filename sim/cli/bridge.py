"""`ctsim bridge`: the real c't-Bot firmware drives robots over c't-Sim's TCP protocol."""

from __future__ import annotations

import argparse
import sys
import threading

from sim.analysis.run_folder import RunFolder
from sim.cli.observers import Progress, StopOnSignal
from sim.cli.options import EXIT_STATUSES, UsageError, add_robot_options, load_robot_spec, param, positive, robot_options, robot_setups, whole
from sim.cli.output import finish, out_dir
from sim.run.clock import MAX_STEP_TIMEOUT
from sim.run.loop import MAX_DURATION, step_count


def add_parser(commands) -> None:
    from sim.bridge.usage import HOW_TO_START

    def timed(parse):
        def convert(text: str):
            from sim.bridge.usage import timed

            try:
                return timed(text, parse)
            except ValueError as err:
                raise argparse.ArgumentTypeError(str(err)) from None

        return convert

    from sim.bridge.protocol import parse_call, rc5_code

    bridge = commands.add_parser(
        "bridge",
        help="let the real c't-Bot firmware drive robots over c't-Sim's TCP protocol",
        description="Listen for c't-Bot firmwares (their PC build) as c't-Sim does and run them in lock-step with the world, "
        "10 ms per step, headless and recorded like `run` (the firmware's LCD, LEDs, motors, log and remote calls too). "
        "Exact unless asked: like c't-Sim, the robots have no noise (--noise none) unless --noise says otherwise.",
        epilog=f"{HOW_TO_START}\n\n{EXIT_STATUSES}",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_robot_options(bridge, noise="none")  # c't-Sim's wheels and sensors are exact
    bridge.add_argument("--robots", type=whole, default=1, metavar="N", help="number of firmware bots (default: 1)")
    bridge.add_argument("--controller", action="append", metavar="NAME|FILE.py[:NAME]", help="also add a robot with this Python controller (repeatable)")
    bridge.add_argument("--param", action="append", type=param, default=[], metavar="KEY=VALUE", help="parameter of the Python controllers")
    bridge.add_argument("--duration", type=positive(float, MAX_DURATION, "s"), default=60.0, metavar="SECONDS", help="simulated time to run (default: 60)")
    bridge.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1, this machine only)")
    bridge.add_argument("--port", type=whole, default=10001, help="TCP port (default: 10001, the firmware's fixed port)")
    bridge.add_argument("--connect-timeout", type=positive(float, MAX_STEP_TIMEOUT, "s"), default=60.0, metavar="SECONDS", help="wait this long for each firmware to connect (default: 60)")
    bridge.add_argument("--step-timeout", type=positive(float, MAX_STEP_TIMEOUT, "s"), default=10.0, metavar="SECONDS",
                        help="a firmware silent this long in one step has hung (default: 10, c't-Sim's)")
    bridge.add_argument("--realtime", action="store_true", help="run at c't-Sim's real time (100 steps/s) instead of as fast as the firmware answers")
    bridge.add_argument("--rc5", action="append", type=timed(rc5_code), default=[], metavar="T:KEY",
                        help="press an RC5 key at T s: 0-9, PWR, UP, DOWN, LEFT, RIGHT, PLAY, CH+, CH-, VOL+, VOL-, I/II or a code (repeatable)")
    bridge.add_argument("--call", action="append", type=timed(parse_call), default=[], metavar="T:'CALL'", help="remote call at T s, e.g. 2:'bot_turn(90)' (repeatable)")
    bridge.add_argument("--list-calls", action="store_true", help="ask each firmware for the remote calls it offers and print them (c't-Sim's RemoteCallViewer)")
    bridge.add_argument("--own-physics", action="store_true",
                        help="firmware bots meet walls (slide), see them (nearest point in the IR cone), read lines at one point "
                        "and meet lamp pillars as whole wall cells, with ctsim's own models instead of c't-Sim's")
    bridge.set_defaults(handler=cmd_bridge)


def cmd_bridge(args: argparse.Namespace) -> int:
    from sim.bridge import Bridge
    from sim.run.loop import run
    from sim.views.figures import headless_pyplot
    from sim.views.recording.arrow import keep_pandas_out_of_arrow
    from sim.views.recording.recorder import Recorder
    from sim.world.files import load_world

    step_count(args.duration, args.dt)
    world = load_world(args.world, pillars="cell" if args.own_physics else "cylinder")
    spec = load_robot_spec(args)
    if args.robots < 1:
        raise UsageError(f"--robots must be at least 1, got {args.robots}")
    room = len(world.start_order())
    python = robot_setups(args, spec, room) if args.controller else []
    if args.robots + len(python) > room:
        raise UsageError(f"{args.robots} firmware bot(s) and {len(python)} Python robot(s), but the world has room for {room} "
                         "(one start slot each); add starts (slot 1, 2, ...) to the world")
    out = out_dir(args.out, args.world, "bridge")
    calls = [(at, f"{name}({', '.join(map(str, params))})") for at, (name, params) in args.call]
    with Bridge(args.host, args.port, args.connect_timeout, args.step_timeout, dt=args.dt, list_calls=args.list_calls) as bridge:
        setups = [bridge.setup(spec, rc5=args.rc5, calls=calls, like_ctsim=not args.own_physics) for _ in range(args.robots)] + python
        print(f"ctsim bridge: listening on {bridge.address} for {args.robots} firmware bot(s); start the firmware now", file=sys.stderr, flush=True)
        keep_pandas_out_of_arrow()
        if not args.no_report:  # (the figures' import, taken while the run waits for the firmware: not after its last block)
            threading.Thread(target=headless_pyplot, name="ctsim: matplotlib").start()  # (not a daemon: an exit waits for its import)
        recorder = Recorder(RunFolder(out).recording, live=args.live)
        with StopOnSignal() as stop:
            observers = (stop.starting, bridge.observer(recorder, realtime=args.realtime), recorder, Progress(args.duration, args.dt), stop)
            result = run(world, setups, args.duration, dt=args.dt, seed=args.seed, observers=observers)
        for bot in bridge.summary():
            if args.list_calls:
                print(f"{bot['label']} offers {len(bot['functions'])} remote calls:" + "".join(f"\n  {f}" for f in bot["functions"]))
            for call in bot["calls"]:
                outcome = f"result {call['result']} at step {call['done_step']}" if call["result"] is not None else "no result (r/D) yet"
                print(f"{bot['label']}: {call['call']} sent at step {call['sent_step']}: {outcome}")
        # the firmwares are shut down when the files are written (leaving the `with`)
        return finish(result, out, {"duration": args.duration, "until_goal": False, **robot_options(args), "bridge": bridge.summary()}, report=not args.no_report, export_rate=args.export_rate)
