#!/usr/bin/env python3
"""The pivot `nlstudy table valid.json --rows m --column threads --value error_l2_norm
--where "n == 64" --where "threads <= 4"` in python-polars, over the same summary table: read,
filter, pivot, print as Markdown. Prints the seconds of each phase after the import. The peer
side of docs/performance.md's "The analysis by hand, or with polars":

    python3 -m venv target/peers/venv && target/peers/venv/bin/pip install polars
    target/peers/venv/bin/python scripts/pivot-polars.py SUMMARY.parquet
"""
import sys, time
t0 = time.perf_counter()
import polars as pl
t1 = time.perf_counter()
df = pl.read_parquet(sys.argv[1])
t2 = time.perf_counter()
kept = df.filter((pl.col("case.n") == 64) & (pl.col("threads") <= 4))
table = kept.pivot(on="threads", index="m", values="error_l2_norm", aggregate_function="first").sort("m")
t3 = time.perf_counter()
with pl.Config(tbl_formatting="MARKDOWN", tbl_rows=-1, tbl_cols=-1):
    out = str(table)
sys.stdout.write(out + "\n")
t4 = time.perf_counter()
print(f"import {t1-t0:.3f} s, read {t2-t1:.3f} s, filter+pivot {t3-t2:.3f} s, print {t4-t3:.3f} s, rows {df.height}", file=sys.stderr)
