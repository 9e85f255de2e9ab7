#!/usr/bin/env python3
"""Calibrate `regolith validate`'s default thresholds on corpus campaigns (stdlib only).

For each seed: generate a `mini` campaign with no hidden effect, add a deliberately degraded
0.05 m laser raster to its terrain list, compile, validate every terrain entry and a negative
control (`regolith control`: laser/0.01 with its texture blurred by σ = 2 cm), and print per
entry the figures the certificate gates on (ratio of the repeatability over chance to the
real-vs-real ceiling per detector, with the chance part of the render's one-directional ratio). The defaults in validator/src/validate.rs
(`Thresholds::default`) are set between the good entries and the degraded one; the figures of
the last calibration are quoted there.

    python3 tools/calibrate/validate_thresholds.py --seeds 311,312,313 --out /tmp/calib \
        --renders corpus/renders-train [--bin target/release/regolith] [--renderer mitsuba|model]

Seeds 311-313 are the training seeds (their renders: corpus/renders-train/); seeds 301-303 are
the held-out test seeds of the independent captures (corpus/renders/): never calibrate on them.
"""
import argparse
import json
import pathlib
import re
import subprocess
import sys


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode not in (0, 1):
        sys.exit(f"{' '.join(map(str, cmd))} failed ({p.returncode}):\n{p.stderr}")
    return p.stdout


def certificate(db, entry_json):
    h = entry_json["certificate"]
    return json.loads((db / "objects" / "sha256" / h[:2] / h[2:]).read_text())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--bin", default="target/release/regolith")
    ap.add_argument("--renders", default=None,
                    help="render cache folder for Mitsuba (corpus/renders-train for the training seeds 311-313, corpus/renders for the test seeds 301-303)")
    ap.add_argument("--renderer", default="mitsuba", choices=["mitsuba", "model"],
                    help="who renders the captures: Mitsuba 3 (independent of the validator; "
                         "default) or the validator's own forward model (the calibration before "
                         "format 1.10; an inverse crime for the figures)")
    a = ap.parse_args()
    rows = []
    for seed in [int(s) for s in a.seeds.split(",")]:
        d = a.out / f"seed{seed}"
        camp, db = d / "campaign", d / "db"
        if not (db / "regolith.db").exists():
            renders = ["--renders", a.renders] if a.renders else []
            run([a.bin, "corpus", "generate", "--renderer", a.renderer, *renders, "--preset", "mini",
                 "--seed", str(seed), "--out", camp])
            toml = (camp / "campaign.toml").read_text()
            toml = re.sub(r"raster_m = \[0\.02, 0\.01\]", "raster_m = [0.05, 0.02, 0.01]", toml, count=1)
            (camp / "campaign.toml").write_text(toml)
            run([a.bin, "compile", camp, "--db", db, "--release", f"mini{seed}@1.0.0"])
        out = json.loads(run([a.bin, "--json", "validate", db]))
        # The negative control: the finest laser raster with its texture blurred by σ = 2 cm.
        ctl = json.loads(run([a.bin, "--json", "control", db, "--release", f"mini{seed}@1.0.0",
                              "--entry", "laser/0.01", "--texture-blur-m", "0.02"]))
        out["entries"] += json.loads(run([a.bin, "--json", "validate", db, "--release", ctl["release"],
                                          "--entry", ctl["entry"]]))["entries"]
        for e in out["entries"]:
            c = certificate(db, e)
            ratios = {k: v["ratio"]["mean"] for k, v in c["summary"].items() if v.get("ratio")}
            chance = {k: v["chance"]["mean"] for k, v in c["summary"].items()}
            ph = c["photometric"]
            rows.append({
                "seed": seed,
                "entry": e["entry"],
                "ratios": ratios,
                "chance": chance,
                "mean_ratio": sum(ratios.values()) / max(len(ratios), 1),
                "rms": sum(p[2]["rms"] for p in ph) / len(ph),
                "high_band_log_ratio": sum(c["spectrum_log_ratio"][4:]) / 4,
                "passed": e["passed"],
            })
            r = rows[-1]
            print(f"seed {seed:3d} {r['entry']:12s} mean ratio {r['mean_ratio']:.3f} "
                  + " ".join(f"{k} {v:.3f} (chance {chance[k]:.3f})" for k, v in sorted(ratios.items()))
                  + f"  rms {r['rms']:.1f}  high-band log ratio {r['high_band_log_ratio']:+.2f}"
                  + f"  {'pass' if r['passed'] else 'fail'}", flush=True)
    (a.out / "calibration.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
