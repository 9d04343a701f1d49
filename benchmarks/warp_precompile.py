"""Compile the MuJoCo Warp kernels that validation needs for a GPU architecture, ahead of time,
on a machine without that GPU.

Why: on first use Warp compiles each kernel module with NVRTC, one at a time as steps launch
them. On an H200 machine (2026-12-04) the Shadow Hand's scene spent 10 s on
``mujoco_warp._src.smooth`` and 31–45 s on each of its convex-collision (``ccd_kernel``) modules,
minutes in all: more than a short GPU lease. Module hashes do not depend on the device or the
number of worlds, so the modules one step loads on Warp's CPU backend here are the ones the GPU
loads (a few CUDA-only variants still compile there); this compiles them for ``--arch`` into
``--out``, two threads at a time. Use the result on the GPU machine with
``WARP_CACHE_PATH=<out>`` (Warp appends its version, as this script's output folder does).

    python benchmarks/warp_precompile.py [--arch 90] [--object 005_tomato_soup_can]
        [--protocols lift-drop,six-dir] [--out /tmp/warp_cache] [--threads 2]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.validator import Validator
from sim.validate.warp_runner import WarpRunner
from sim.world.objects import load_object


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--arch", type=int, default=90, help="CUDA compute capability (H100/H200: 90)")
    parser.add_argument("--object", default="005_tomato_soup_can")
    parser.add_argument("--hand", default=None, help="hand config (default: the default hand)")
    parser.add_argument("--protocols", default="lift-drop,six-dir")
    parser.add_argument("--out", type=Path, default=Path("/tmp/warp_cache"))
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    import warp as wp

    wp.config.kernel_cache_dir = str(args.out)   # Warp adds its version: out/<version>/
    wp.config.quiet = True
    v = Validator(Hand.load(args.hand or default_hand_name()), load_object(args.object))
    for protocol in args.protocols.split(","):
        runner = WarpRunner(v.scene(protocol), 2, "cpu", capture=False)
        runner.load_kernels()
    from warp._src.context import user_modules

    modules = [m for m in user_modules.values() if m.execs]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(args.threads) as pool:
        list(pool.map(lambda m: wp.compile_aot_module(m, arch=args.arch, use_ptx=False), modules))
    print(f"{len(modules)} modules compiled for sm_{args.arch} in {time.perf_counter() - t0:.0f} s "
          f"into {args.out / wp.config.version}; on the GPU machine: WARP_CACHE_PATH={args.out}")


if __name__ == "__main__":
    main()
