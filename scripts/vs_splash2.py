#!/usr/bin/env python3
"""Interleaved speed comparison of radlab with the SPLASH-2 `radiosity` program.

The host's speed drifts by up to +-30 % within minutes, so absolute times from different minutes
cannot be compared. This script alternates the two programs: each round runs SPLASH-2 once
(single thread, batch mode, its built-in room at its defaults: area epsilon 2000, BF epsilon
0.015, energy epsilon 0.005) and `radlab speed` (builtin:splash_room, preset splash2) once, and
reports the medians and the median of the per-round ratios.

SPLASH-2's code is not part of radlab (its licence forbids redistribution). Build it yourself
(e.g. from the PARSEC 3.0 `ext/splash2/apps/radiosity` sources, gcc -O3, graphics library
stubbed out, batch mode only) and pass the binary:

    cargo build --release --no-default-features
    python3 scripts/vs_splash2.py PATH/TO/radiosity --rounds 10

SPLASH-2's time is the CPU time (user + system) of the whole process, as in the issue's figure
(0.83 s); radlab's is the wall time of one solve (median of `--repeats` solves after a warm-up).
"""

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile

ISSUE_SPLASH2_CPU_S = 0.83  # the issue's figure for SPLASH-2 on this class of machine


def run_splash2(binary):
    """One SPLASH-2 run: (CPU seconds of the process, elements, interactions)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(
        [binary, "-p", "1", "-batch", "-room"], check=True, capture_output=True, text=True
    ).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    elements = re.search(r"Total number of elements:\s*(\d+)", out)
    links = re.search(r"Total number of interactions:\s*(\d+)", out)
    if not (elements and links):
        sys.exit(f"{binary}: no statistics in its output (is it SPLASH-2 radiosity in batch mode?)")
    return cpu, int(elements.group(1)), int(links.group(1))


def run_radlab(binary, rays, threads, repeats, json_path):
    """One `radlab speed` row: (median wall seconds of a solve, elements, leaves, links)."""
    subprocess.run(
        [binary, "speed", "--rays", str(rays), "--threads", str(threads),
         "--repeats", str(repeats), "--json", json_path],
        check=True, capture_output=True, text=True,
    )
    with open(json_path) as f:
        row = json.load(f)[0]
    return row["total_s"], row["elements"], row["leaves"], row["links"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("splash2", help="the SPLASH-2 radiosity binary")
    ap.add_argument("--radlab", default="target/release/radlab", help="the radlab binary")
    ap.add_argument("--rounds", type=int, default=10, help="alternations (default 10)")
    ap.add_argument("--repeats", type=int, default=3, help="radlab solves per round (default 3)")
    ap.add_argument("--json", help="write every round's figures here")
    args = ap.parse_args()
    for b in (args.splash2, args.radlab):
        if not os.access(b, os.X_OK):
            sys.exit(f"{b}: not an executable file")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "speed.json")
        for r in range(args.rounds):
            s_cpu, s_el, s_links = run_splash2(args.splash2)
            t4, el, leaves, links = run_radlab(args.radlab, 4, 2, args.repeats, path)
            t10, *_ = run_radlab(args.radlab, 10, 1, args.repeats, path)
            rows.append({"splash2_cpu_s": s_cpu, "radlab_4rays_2threads_s": t4,
                         "radlab_10rays_1thread_s": t10})
            print(f"round {r + 1}/{args.rounds}: SPLASH-2 {s_cpu:.3f} s CPU, "
                  f"radlab {t4:.4f} s (4 rays, 2 threads), {t10:.4f} s (10 rays, 1 thread)",
                  file=sys.stderr)
    med = lambda key: statistics.median(x[key] for x in rows)
    ratio4 = statistics.median(x["splash2_cpu_s"] / x["radlab_4rays_2threads_s"] for x in rows)
    ratio10 = statistics.median(x["splash2_cpu_s"] / x["radlab_10rays_1thread_s"] for x in rows)
    print(f"SPLASH-2 radiosity: {s_el} elements, {s_links} links; "
          f"median {med('splash2_cpu_s'):.3f} s CPU (one thread, whole process)")
    print(f"radlab splash2 preset: {el} elements ({leaves} leaves), {links} links")
    print(f"  4 rays, 2 threads:  median {med('radlab_4rays_2threads_s'):.4f} s wall; "
          f"SPLASH-2 / radlab {ratio4:.2f} (median of rounds); at SPLASH-2 = "
          f"{ISSUE_SPLASH2_CPU_S} s that is {ISSUE_SPLASH2_CPU_S / ratio4:.3f} s")
    print(f"  10 rays, 1 thread:  median {med('radlab_10rays_1thread_s'):.4f} s wall; "
          f"SPLASH-2 / radlab {ratio10:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rounds": rows, "ratio_4rays_2threads": ratio4,
                       "ratio_10rays_1thread": ratio10}, f, indent=1)


if __name__ == "__main__":
    main()
