#!/usr/bin/env python3
"""The GPU issue's targets against what `scripts/gpu-check.sh` measured.

    scripts/gpu-targets.py DIR      (DIR: the check's output, default /tmp/gpu-check)

Reads DIR/rectum-gpu.jsonl, DIR/cholecystectomy-gpu.jsonl (`vesalius bench <p> --compute gpu
--json`), DIR/profile-gpu.jsonl, DIR/profile-shared.jsonl (the same frames with the models on
the frames' device) and DIR/gpu.txt (nvidia-smi's name line), and prints one JSON
object: each target with what was measured and whether it was met (null where nothing was
measured). The card's peak bandwidth comes from GPU_PEAK_GBS, or from the table below by the
GPU's name.
"""

import json
import os
import sys

# Memory bandwidth of data-centre cards, GB/s (the makers' sheets).
PEAK_GBS = {
    "H200": 4800.0,
    "H100 SXM": 3350.0,
    "H100 NVL": 3900.0,
    "H100 PCIe": 2000.0,
    "A100-SXM4-80GB": 2039.0,
    "A100 80GB PCIe": 1935.0,
    "A100-SXM4-40GB": 1555.0,
    "L40S": 864.0,
}

# The headset's frame at 90 Hz, ms.
FRAME_MS = 1000.0 / 90.0


def lines(path):
    """The JSON lines of a file (none where it is missing or a line is not JSON)."""
    out = []
    try:
        with open(path, encoding="utf-8") as f:
            for raw in f:
                raw = raw.strip()
                if not raw:
                    continue
                try:
                    out.append(json.loads(raw))
                except json.JSONDecodeError:
                    pass
    except OSError:
        pass
    return out


def line(rows, model):
    """The first bench line of `model`, or None."""
    return next((r for r in rows if r.get("model") == model), None)


def peak_gbs(out_dir):
    """The card's peak bandwidth, GB/s, and where it came from."""
    env = os.environ.get("GPU_PEAK_GBS")
    if env:
        try:
            return float(env), "GPU_PEAK_GBS"
        except ValueError:
            pass
    try:
        with open(os.path.join(out_dir, "gpu.txt"), encoding="utf-8") as f:
            name = f.readline()
    except OSError:
        return None, None
    for key in sorted(PEAK_GBS, key=len, reverse=True):
        if key.lower() in name.lower():
            return PEAK_GBS[key], key
    return None, name.strip() or None


def target(what, measured, goal, at_least=True, aim=None):
    """One target: `measured` against `goal` (at least, or at most)."""
    met = None
    if measured is not None:
        met = measured >= goal if at_least else measured <= goal
    row = {"target": what, "measured": measured, "goal": goal, "met": met}
    if aim is not None:
        row["aim"] = aim
    return row


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "/tmp/gpu-check"
    rectum = lines(os.path.join(out_dir, "rectum-gpu.jsonl"))
    chole = lines(os.path.join(out_dir, "cholecystectomy-gpu.jsonl"))
    frames = lines(os.path.join(out_dir, "profile-gpu.jsonl"))
    membrane = line(rectum, "membrane")
    particles = line(chole, "particles_without_instruments")
    get = lambda row, key: None if row is None else row.get(key)
    procedure = lambda rows: line(rows, "procedure")
    # (what, its bench line, the key, the goal, at least (or at most), the aim)
    table = [
        ("membrane at 960,000 nodes all awake, substeps/s (wall)",
         membrane, "substeps_per_s", 27000.0, True, 40500.0),
        ("membrane, substeps/s (GPU clock)",
         membrane, "kernel_substeps_per_s", 27000.0, True, None),
        ("membrane, step-to-force latency p99, ms",
         membrane, "latency_p99_ms", 1.0, False, None),
        ("rectum procedure, times real time",
         procedure(rectum), "realtime_factor", 1.5, True, None),
        ("rectum procedure, a step's CPU part outside the device (mean), ms",
         procedure(rectum), "step_cpu_ms_mean", 0.67, False, None),
        ("rectum procedure, a whole step to its tool forces (p99), ms",
         procedure(rectum), "step_ms_p99", 1.0, False, None),
        ("rectum procedure, its slowest simulated second, times real time",
         procedure(rectum), "realtime_factor_slowest_s", 1.0, True, None),
        ("cholecystectomy solver all awake, times real time",
         particles, "realtime_factor", 1.5, True, 3.0),
        ("cholecystectomy solver, step latency p99, ms",
         particles, "latency_p99_ms", 1.0, False, None),
        ("cholecystectomy procedure, times real time",
         procedure(chole), "realtime_factor", 1.5, True, None),
        ("cholecystectomy procedure, a step's CPU part outside the device (mean), ms",
         procedure(chole), "step_cpu_ms_mean", 0.67, False, None),
        ("cholecystectomy procedure, a whole step to its tool forces (p99), ms",
         procedure(chole), "step_ms_p99", 1.0, False, None),
        ("cholecystectomy procedure, its slowest simulated second, times real time",
         procedure(chole), "realtime_factor_slowest_s", 1.0, True, None),
    ]
    rows = [
        target(what, get(row, key), goal, at_least=least, aim=aim)
        for (what, row, key, goal, least, aim) in table
    ]
    for f in frames:
        name = f.get("profile")
        beside = f.get("beside") or {}
        rows.append(
            target(
                "stereo frame at 1080 x 1200 a eye, %s, alone (mean), ms" % name,
                f.get("frame_ms"),
                FRAME_MS,
                at_least=False,
            )
        )
        # The frame: drawn at 90 Hz with the simulation running beside it; every
        # frame must make it, so the 99th percentile stands for them.
        rows.append(
            target(
                "stereo frame at 1080 x 1200 a eye, %s, the simulation beside it (p99), ms"
                % name,
                beside.get("frame_ms_p99"),
                FRAME_MS,
                at_least=False,
            )
        )
        # Paced to the wall clock, the simulation is at most 1 x real time there: this says
        # whether it kept up while the frames were drawn.
        rows.append(
            target(
                "%s simulation beside the frames, times real time (paced: 1 at most)" % name,
                beside.get("realtime_factor"),
                0.99,
            )
        )
    peak, source = peak_gbs(out_dir)
    gbs = get(membrane, "gb_per_s")
    share = None if peak is None or gbs is None else gbs / peak
    bandwidth = {
        "membrane_gb_per_s": gbs,
        "peak_gb_per_s": peak,
        "peak_from": source,
        "share_of_peak": share,
    }
    # Every layout of the membrane's workgroups side by side (the targets take the default's
    # line, `membrane`; a faster layout is the next default).
    layouts = {
        r.get("model"): {
            "substeps_per_s": r.get("substeps_per_s"),
            "kernel_substeps_per_s": r.get("kernel_substeps_per_s"),
        }
        for r in rectum
        if str(r.get("model", "")).startswith("membrane")
    }
    # The procedures with a GPU path drawn with their models on the frames' own device (one
    # wgpu device and queue) beside the same on two devices: no target, the figures to choose
    # by.
    shared = lines(os.path.join(out_dir, "profile-shared.jsonl"))
    keys = ("frame_ms_p99", "realtime_factor", "force_gap_ms_median", "force_gap_ms_p99")
    one_or_two = {}
    for f in shared:
        name = f.get("profile")
        two = next((g for g in frames if g.get("profile") == name), {})
        one_or_two[name] = {
            "one_device": {k: (f.get("beside") or {}).get(k) for k in keys},
            "two_devices": {k: (two.get("beside") or {}).get(k) for k in keys},
            "devices_opened_shared": f.get("gpu_devices"),
        }
    measured = [r for r in rows if r["met"] is not None]
    print(
        json.dumps(
            {
                "targets": rows,
                "bandwidth": bandwidth,
                "membrane_layouts": layouts,
                "one_device_or_two": one_or_two,
                "met": sum(1 for r in measured if r["met"]),
                "measured": len(measured),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
