#!/usr/bin/env python3
"""Run `regolith validate` as shards on a Ray cluster, then merge them into certificates.

Each shard is one Ray task that runs the `regolith` binary on the worker it lands on:
`regolith --json validate DB ... --shard I/N`. The shards store their unit results in the
database, so every worker must reach the same database (an object-store URL, or a folder on a
shared file system). A task whose worker dies, or whose `regolith` fails, is retried (Ray's
`max_retries`, with `retry_exceptions`); a retried shard skips the units its first attempt
stored. When every shard has finished, the driver runs `regolith validate ... --merge` where
it runs and prints that command's JSON: the certificates a single process would write, byte
for byte.

Usage (see docs/distributed.md):

    python3 tools/distributed/ray_validate.py --address auto --db s3://bucket/terrain \
        --shards 64 --entry laser/0.01 [--release R] [--detector D]... [--thresholds FILE]

Progress goes to stderr, one line per finished shard; stdout is the merge's JSON.
Exit code: the merge's (0 every entry passed, 1 an entry failed, 2 an error), or 3 when a
shard failed after all its retries.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Sharded `regolith validate` on a Ray cluster, merged into certificates.")
    p.add_argument("--address", default="auto",
                   help="Ray cluster address (default: auto, the cluster this machine is in)")
    p.add_argument("--regolith", default=None,
                   help="path of the regolith binary on the workers (default: `regolith` on PATH)")
    p.add_argument("--db", required=True, help="the database: a folder every worker sees, or a URL")
    p.add_argument("--release", default="latest")
    p.add_argument("--entry", action="append", default=[], help="repeatable; default: all")
    p.add_argument("--detector", action="append", default=[], help="repeatable; default: all")
    p.add_argument("--thresholds", default=None, help="a thresholds JSON file every worker sees")
    p.add_argument("--shards", type=int, required=True, help="number of shards (tasks)")
    p.add_argument("--retries", type=int, default=3,
                   help="retries of a shard whose worker died or whose command failed (default 3)")
    p.add_argument("--cpus-per-shard", type=float, default=1.0,
                   help="CPUs Ray reserves per shard task (default 1)")
    args = p.parse_args(argv)
    if args.shards < 1:
        p.error("--shards must be at least 1")
    if args.retries < 0:
        p.error("--retries must be 0 or more")
    return args


def validate_args(args):
    """The `validate` arguments every shard and the merge share."""
    out = ["--json", "--quiet", "validate", args.db, "--release", args.release]
    for e in args.entry:
        out += ["--entry", e]
    for d in args.detector:
        out += ["--detector", d]
    if args.thresholds:
        out += ["--thresholds", args.thresholds]
    return out


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        import ray
    except ImportError:
        sys.exit("ray_validate: the Python package `ray` is not installed "
                 "(python3 -m pip install 'ray[default]==2.60.0')")
    binary = args.regolith or shutil.which("regolith") or "regolith"
    common = validate_args(args)

    @ray.remote(num_cpus=args.cpus_per_shard, max_retries=args.retries, retry_exceptions=True)
    def shard(index, count):
        cmd = [binary] + common + ["--shard", f"{index}/{count}"]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(
                f"shard {index}/{count} on {os.uname().nodename}: `{' '.join(cmd)}` exited "
                f"{done.returncode}: {done.stderr.strip()[-2000:]}")
        return json.loads(done.stdout)

    # Ray writes notices (a node died, a task is retried) to file descriptor 1 from its own
    # threads: send fd 1 to stderr while Ray runs, so stdout carries the merge's JSON alone.
    stdout = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    ray.init(address=args.address, logging_level="ERROR", log_to_driver=False)
    start = time.monotonic()
    pending = {shard.remote(i, args.shards): i for i in range(1, args.shards + 1)}
    finished = 0
    failed = []
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            i = pending.pop(ref)
            try:
                r = ray.get(ref)
                finished += 1
                print(f"[{time.monotonic() - start:6.1f} s] shard {i}/{args.shards} done "
                      f"({r['computed']} computed, {r['reused']} already stored); "
                      f"{finished}/{args.shards} shards", file=sys.stderr, flush=True)
            except Exception as e:  # a shard that failed after its retries
                failed.append(i)
                print(f"[{time.monotonic() - start:6.1f} s] shard {i}/{args.shards} FAILED after "
                      f"{args.retries} retries: {e}", file=sys.stderr, flush=True)
    ray.shutdown()
    if failed:
        print(f"ray_validate: {len(failed)} shard(s) failed ({', '.join(map(str, failed))}); "
              f"their stored units are kept: run again to finish them", file=sys.stderr)
        return 3
    print(f"[{time.monotonic() - start:6.1f} s] merging", file=sys.stderr, flush=True)
    merged = subprocess.run([binary] + common + ["--merge"], capture_output=True, text=True)
    stdout.write(merged.stdout)
    stdout.flush()
    sys.stderr.write(merged.stderr)
    return merged.returncode


if __name__ == "__main__":
    sys.exit(main())
