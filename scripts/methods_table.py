#!/usr/bin/env python3
"""Markdown tables for docs/methods.md from the CSVs scripts/methods_docs.sh
writes (docs/methods/<scene>.csv): one row per method and setting, frame time
relative to raymarch (ms=off) in the same run, and rel-L2 against the
pathtrace truth. Usage: scripts/methods_table.py docs/methods/*.csv"""
import csv
import os
import sys

for path in sys.argv[1:]:
    rows = list(csv.DictReader(open(path)))
    if not rows:
        continue
    scene = os.path.basename(path)[:-4]
    base = next((float(r["frame_ms_median"]) for r in rows
                 if r["method"] == "raymarch" and "ms=off" in r["params"]), None)
    r0 = rows[0]
    print(f"#### {scene}\n")
    print(f"![{scene}: error against time](images/methods/{scene}.png)\n")
    print("| method | setting | frame time / raymarch | rel-L2 vs pathtrace |")
    print("|---|---|---|---|")
    for r in rows:
        t = float(r["frame_ms_median"])
        ratio = f"{t / base:.2f}" if base else "–"
        print(f"| {r['method']} | {r['params'] or '–'} | {ratio} | {float(r['rel_l2_vs_pathtrace']):.3f} |")
    print(f"\nConditions: {r0['width']}×{r0['height']}, CPU, {r0['threads']} threads, load average "
          f"{r0['load_avg']}; truth {r0['truth']}.\n")
