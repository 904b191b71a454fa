"""Settlement against friction over many beds and trains (issue #8; seed 004 §4.1).

  track_ensemble.py --pack BIN --qdem BIN --post BIN --seeds N [--speeds "115 160"] --out DIR

Seed 004 §4.1 finds that the sleeper settles less as the friction coefficient rises
from 0.577 to 1.73. One run per friction on one bed is one sample of a chaotic
process (which stones slide first), so this runs the comparison over N beds (seeds
1..N of `ballast-pack --preset impact-quick`) and over trains: for each bed and each
speed, the first bogie of one car (`ballast-post train-load --cars 1`, 120 kN axles,
the first axle 1.885 m before the sleeper, a roughness realisation of the bed's seed,
6.39 m of travel) passes over the sleeper, once with µ = 0.577 and once with µ = 1.73 on every contact
(`ballast-qdem scenes/track_impact.toml --preset quick`, 2 threads). The two runs of a
pair see the same bed and the same load.

The table gives per bed and train the sleeper's settlement between the two axles
(after the first has passed: the time halfway between them over the sleeper) and at
the end of the record (the second axle 2.3 m past it), at both frictions, and the
stone sensors' (B1–B3, 10 cm under the sleeper) mean vertical displacement at the end; then how
many pairs keep seed 004's ordering, the mean settlements, and the paired differences
(µ = 0.577 minus µ = 1.73, in mm of settlement) with their standard error and 95 %
interval. Beds, loads and runs already in DIR (with their summary.json) are reused.
"""

import csv
import json
import os
import statistics
import subprocess
import sys

import ensemble as ensemble_tools

MUS = ("0.577", "1.73")
LEAD_IN_M = 1.885   # a zero of the rail's influence line (mk/track-load.mk)
AXLE_BASE_M = 2.1   # ballast-post train-load's default bogie
TAG = "track_ensemble"


def train_load(post, speed, seed, out):
    """The first bogie at SPEED km/h with the roughness of SEED, recorded until it has
    run 6.39 m (0.2 s at 115 km/h, the track study's record: its second axle 2.3 m past
    the sleeper, the load back to zero); returns (path, the times the two axles are
    over the sleeper, the record's length). The roughness is drawn over the whole
    record, so only the same length gives the same realisation."""
    v = speed / 3.6
    t1, t2 = LEAD_IN_M / v, (LEAD_IN_M + AXLE_BASE_M) / v
    duration = 0.2 * 115.0 / speed
    path = os.path.abspath(os.path.join(out, "load-%g-%d.csv" % (speed, seed)))
    if not os.path.exists(path):
        subprocess.run([post, "train-load", "--out", path, "--cars", "1", "--lead-in-m", str(LEAD_IN_M),
                        "--speed-km-h", str(speed), "--seed", str(seed), "--duration-s", "%.4f" % duration],
                       check=True, stdout=subprocess.DEVNULL)
    return path, (t1, t2), duration


def settlement_at(directory, t):
    """The sleeper's settlement (m) in DIR/track.csv at the last row at or before T."""
    value = float("nan")
    with open(os.path.join(directory, "track.csv")) as f:
        for row in csv.DictReader(f):
            if float(row["time_s"]) > t:
                break
            value = float(row["sleeper_settlement_m"])
    return value


def stone_settlement(directory):
    """The mean vertical displacement (m) of the stone sensors (B*) at the end of
    DIR/sensors.csv (seed 004 Figure 8b plots it as the ballast settlement; on rigid
    10 cm stones it also carries their turning)."""
    with open(os.path.join(directory, "sensors.csv")) as f:
        reader = csv.reader(f)
        header = next(reader)
        last = None
        for last in reader:
            pass
    values = [float(last[i]) for i, h in enumerate(header) if h.startswith("B") and h.endswith("_uz_m")]
    return statistics.mean(values)


def rail_hold(directory):
    """The rails' hold the run in DIR had (its summary's `rail` inputs), as text."""
    with open(os.path.join(directory, "summary.json")) as f:
        rail = json.load(f)["inputs"].get("rail")
    if not rail:
        return "none (a scene without [rail])"
    return "%s along the track, %s along the sleeper, per rail seat" % (rail["longitudinal"], rail["lateral"])


def main(argv):
    opts = dict(zip(argv[0::2], argv[1::2]))
    if not {"--pack", "--qdem", "--post"} <= opts.keys():
        print(__doc__, file=sys.stderr)
        return 2
    seeds = int(opts.get("--seeds", "6"))
    speeds = [float(s) for s in opts.get("--speeds", "115").split()]
    out = opts.get("--out", "results/track-mu-ensemble")
    os.makedirs(out, exist_ok=True)
    rows = []
    for seed in range(1, seeds + 1):
        packing, bed = ensemble_tools.pack_bed(opts["--pack"], "impact-quick", seed, out, TAG)
        for speed in speeds:
            load, (t1, t2), duration = train_load(opts["--post"], speed, seed, out)
            runs = {}
            for mu in MUS:
                d = os.path.join(out, "track-%d-%g-mu%s" % (seed, speed, mu))
                figures = ensemble_tools.run_once(
                    [opts["--qdem"], "scenes/track_impact.toml", "--preset", "quick", "--threads", "2",
                     "--set", 'track.packing="%s"' % packing, "--set", 'track.loads="%s"' % load,
                     "--set", 'track.duration="%.4f s"' % duration, "--set", "track.frames=0",
                     "--set", "track.checkpoint_every=0"]
                    + [a for key in ("ballast_ballast", "ballast_sleeper", "base")
                       for a in ("--set", "friction.%s=%s" % (key, mu))],
                    d, TAG, "bed %d, %g km/h, µ = %s" % (seed, speed, mu))
                runs[mu] = (settlement_at(d, (t1 + t2) / 2), figures["sleeper_settlement_m"],
                            stone_settlement(d))
            rows.append((seed, speed, bed["grains"], runs))
            last_run = d

    print("\n## Sleeper settlement at µ = 0.577 and µ = 1.73 over %d impact-quick beds (first bogie, 120 kN axles)\n"
          % seeds)
    print("The rails' hold on the sleeper: %s.\n" % rail_hold(last_run))
    print("| bed seed | stones | km/h | sleeper between the axles: µ 0.577 / 1.73 (mm) | sleeper at the end: µ 0.577 / 1.73 (mm) | ordering (between / end) | stone sensors B1–B3 at the end, mean uz: µ 0.577 / 1.73 (mm) |")
    print("|---|---|---|---|---|---|---|")
    keys = ("between", "end")
    labels = {"between": "sleeper between the axles", "end": "sleeper at the end"}
    held = {k: 0 for k in keys}
    diffs = {k: [] for k in keys}
    for seed, speed, grains, runs in rows:
        lo, hi = runs[MUS[0]], runs[MUS[1]]
        for i, key in enumerate(keys):
            # settlement is negative downwards: more settlement at low µ is lo < hi
            diffs[key].append(hi[i] - lo[i])
            held[key] += lo[i] < hi[i]
        print("| %d | %d | %g | %.3f / %.3f | %.3f / %.3f | %s | %.3f / %.3f |"
              % (seed, grains, speed, 1e3 * lo[0], 1e3 * hi[0], 1e3 * lo[1], 1e3 * hi[1],
                 " / ".join("yes" if lo[i] < hi[i] else "no" for i in (0, 1)), 1e3 * lo[2], 1e3 * hi[2]))
    n = len(rows)
    for i, key in enumerate(keys):
        means = [statistics.mean(r[3][mu][i] for r in rows) for mu in MUS]
        p = ensemble_tools.sign_test(held[key], n)
        print("\n%s: seed 004's ordering (less settlement at µ = 1.73) in %d of %d pairs (sign test p = %.2g); "
              "mean settlement %.3f mm at µ = 0.577, %.3f mm at µ = 1.73"
              % (labels[key], held[key], n, p, 1e3 * means[0], 1e3 * means[1]))
        print("settlement at µ = 0.577 beyond that at µ = 1.73, " + ensemble_tools.paired_line(
            diffs[key], unit="mm", scale=1e3,
            samples="pairs (%d beds × %d trains: the pairs on one bed share it)" % (seeds, len(speeds))))
        if len(speeds) > 1:
            # the beds are the independent samples: average each bed's trains
            per_bed = [statistics.mean(d for (seed, *_), d in zip(rows, diffs[key]) if seed == b)
                       for b in range(1, seeds + 1)]
            k = sum(d > 0 for d in per_bed)
            p = ensemble_tools.sign_test(k, seeds)
            print("per bed (its %d trains averaged): in seed 004's order on %d of %d beds (sign test p = %.2g); %s"
                  % (len(speeds), k, seeds, p, ensemble_tools.paired_line(per_bed, unit="mm", scale=1e3)))
    stones = [statistics.mean(r[3][mu][2] for r in rows) for mu in MUS]
    print("\nstone sensors B1–B3, mean vertical displacement at the end: %.3f mm at µ = 0.577, %.3f mm at "
          "µ = 1.73 (a point on a rigid stone: it turns and drifts with it, so this is not a settlement "
          "measure on a bed of 10 cm stones)" % (1e3 * stones[0], 1e3 * stones[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
