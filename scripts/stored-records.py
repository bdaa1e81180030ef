#!/usr/bin/env python3
"""Writes one stored record per point of a study's single `product` sweep, made from one real
record: keys as the store computes them, one in 20 failed. For the planning and collect
benchmarks (scripts/bench-planning, scripts/bench-collect).

    scripts/stored-records.py TEMPLATE_RUNS_DIR STUDY.json OUT_RUNS_DIR
"""
import glob, hashlib, itertools, json, os, sys
template = json.load(open(glob.glob(os.path.join(sys.argv[1], "*.json"))[0]))
study = json.load(open(sys.argv[2]))
out = sys.argv[3]
os.makedirs(out, exist_ok=True)
axes = study["sweep"][0]["product"]
names = sorted(axes)
for i, values in enumerate(itertools.product(*(axes[k] for k in names))):
    case = dict(template["case"], **study["base"], **dict(zip(names, values)))
    text = json.dumps(case, separators=(",", ":"), sort_keys=True)
    record = dict(template, case=case, nodes=case["n"], m=case["m"], threads=case["threads"])
    record["case_id"] = hashlib.sha256(text.encode()).hexdigest()[:32]
    record["key"] = hashlib.sha256((text + "\n" + template["solver_version"]).encode()).hexdigest()[:32]
    if i % 20 == 7:
        record.update(status="failed", message="nlsolve exited with signal 9 (killed)\nsecond line")
    with open(os.path.join(out, record["key"] + ".json"), "w") as f:
        f.write(json.dumps(record, separators=(",", ":")) + "\n")
