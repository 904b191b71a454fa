"""What the ensemble studies share (tools/tamping_report.py ensemble, tools/track_ensemble.py):
beds of one ballast-pack preset over seeds 1..N, reused when already built, and the
statistics of paired differences over them.

One run on one small bed is chaotic (the order of the contact updates, a stone more or
less under the sleeper, change the outcome), so a claim such as "async within 2 % of
sync" or "settlement falls as µ rises" is a claim about means over beds, with the
scatter of the paired differences beside it.
"""

import json
import math
import os
import statistics
import subprocess
import sys


def pack_bed(pack, preset, seed, out, tag):
    """The packing of `ballast-pack scenes/bed.toml --preset PRESET` with this seed, in
    OUT/bed-SEED (built unless its summary.json is there), as (absolute packing path,
    the summary's figures)."""
    bed = os.path.join(out, "bed-%d" % seed)
    if not os.path.exists(os.path.join(bed, "summary.json")):
        print("%s: packing the %s bed of seed %d" % (tag, preset, seed), file=sys.stderr, flush=True)
        subprocess.run([pack, "scenes/bed.toml", "--preset", preset, "--set", "seed=%d" % seed,
                        "--set", "output.frame_interval=0", "--set", "output.checkpoint_every=0",
                        "--threads", "2", "--out", bed],
                       check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(bed, "summary.json")) as f:
        figures = json.load(f)["figures"]
    return os.path.abspath(os.path.join(bed, "packing.toml")), figures


def run_once(cmd, directory, tag, what):
    """Runs CMD (which writes DIRECTORY/summary.json) unless that summary is there, and
    returns the summary's figures."""
    summary = os.path.join(directory, "summary.json")
    if not os.path.exists(summary):
        print("%s: %s" % (tag, what), file=sys.stderr, flush=True)
        subprocess.run(cmd + ["--out", directory], check=True, stdout=subprocess.DEVNULL)
    with open(summary) as f:
        return json.load(f)["figures"]


def paired_line(diffs, unit="%", scale=100.0, samples="beds"):
    """Mean, standard deviation and standard error of paired differences, and a 95 %
    interval of the mean (Student t for small samples), as one line; SAMPLES names what
    the differences were taken over."""
    n = len(diffs)
    mean = statistics.mean(diffs) * scale
    if n < 2:
        return "paired difference %+.2f %s (one sample: no spread)" % (mean, unit)
    sd = statistics.stdev(diffs) * scale
    se = sd / n ** 0.5
    t = T95[max(k for k in T95 if k <= n - 1)] if n - 1 <= 30 else 1.96
    return ("paired differences: mean %+.2f %s, sd %.2f %s, standard error %.2f %s, "
            "95 %% interval %+.2f to %+.2f %s over %d %s"
            % (mean, unit, sd, unit, se, unit, mean - t * se, mean + t * se, unit, n, samples))


def sign_test(k, n):
    """One-sided sign test: the chance of at least K of N pairs in one order if either
    order were as likely."""
    return sum(math.comb(n, j) for j in range(k, n + 1)) / 2 ** n


# Two-sided 95 % quantiles of Student's t by degrees of freedom (above 30: 1.96 is
# within 4 % of them).
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131,
       16: 2.120, 17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 25: 2.060, 30: 2.042}
