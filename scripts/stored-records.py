#!/usr/bin/env python3
"""Writes one stored record per point of a study's single `product` sweep, made from one real
record: keys as the store computes them, one in 20 failed. For the planning and collect
benchmarks (scripts/bench-planning, scripts/bench-collect). The records go into segments as
nlstudy writes them (runs/segments/*.seg: frames `nlrecord <seq> <length> <crc32>` and the
record, a new segment past 64 MiB), or with --files into the store's older layout, a file per
record (runs/<key>.json), which nlstudy reads and moves into segments.

    scripts/stored-records.py TEMPLATE_RUNS_DIR STUDY.json OUT_RUNS_DIR [--files]
"""
import glob, hashlib, itertools, json, os, sys, time, zlib


def template_record(runs):
    """The latest record of the template store: from its segments, else its files."""
    for path in sorted(glob.glob(os.path.join(runs, "segments", "*.seg"))):
        data = open(path, "rb").read()
        header, _, rest = data.partition(b"\n")
        length = int(header.split(b" ")[2])
        return json.loads(rest[:length])
    return json.load(open(glob.glob(os.path.join(runs, "*.json"))[0]))


template = template_record(sys.argv[1])
study = json.load(open(sys.argv[2]))
out = sys.argv[3]
files = "--files" in sys.argv[4:]
os.makedirs(os.path.join(out, "segments"), exist_ok=True)
axes = study["sweep"][0]["product"]
names = sorted(axes)
seq = time.time_ns()
segment, written = None, 0
for i, values in enumerate(itertools.product(*(axes[k] for k in names))):
    case = dict(template["case"], **study["base"], **dict(zip(names, values)))
    text = json.dumps(case, separators=(",", ":"), sort_keys=True)
    record = dict(template, case=case, nodes=case["n"], m=case["m"], threads=case["threads"])
    record["case_id"] = hashlib.sha256(text.encode()).hexdigest()[:32]
    record["key"] = hashlib.sha256((text + "\n" + template["solver_version"]).encode()).hexdigest()[:32]
    if i % 20 == 7:
        record.update(status="failed", message="nlsolve exited with signal 9 (killed)\nsecond line")
    body = (json.dumps(record, separators=(",", ":")) + "\n").encode()
    if files:
        with open(os.path.join(out, record["key"] + ".json"), "wb") as f:
            f.write(body)
        continue
    if segment is None or written > 64 << 20:
        if segment:
            segment.close()
        name = "%016x-%d.seg" % (seq, os.getpid())
        segment, written = open(os.path.join(out, "segments", name), "wb"), 0
    seq += 1
    frame = b"nlrecord %d %d %08x\n" % (seq, len(body), zlib.crc32(body)) + body
    segment.write(frame)
    written += len(frame)
if segment:
    segment.close()
