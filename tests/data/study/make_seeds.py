#!/usr/bin/python3
"""Expected cell seeds of the stiffid study runner, computed independently of its C++ code.

Documented rule (validation/study_spec.hpp): identity = canonical JSON (sorted keys, no spaces) of
{"design": NAME, "levels": {...}, "replicate": R}; h = FNV-1a 64 of its bytes;
seed = splitmix64(splitmix64(study_seed) XOR h). Writes seeds.json next to this script.
"""
import json
import os

MASK = (1 << 64) - 1


def splitmix64(x):
    x = (x + 0x9E3779B97F4A7C15) & MASK
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK
    return x ^ (x >> 31)


def fnv1a64(data):
    h = 0xCBF29CE484222325
    for b in data:
        h ^= b
        h = (h * 0x100000001B3) & MASK
    return h


def cell_seed(study_seed, design, levels, replicate):
    identity = json.dumps({"design": design, "levels": levels, "replicate": replicate},
                          sort_keys=True, separators=(",", ":"))
    return splitmix64(splitmix64(study_seed) ^ fnv1a64(identity.encode("ascii")))


cases = [
    {"study_seed": 0, "design": "d", "levels": {}, "replicate": 0},
    {"study_seed": 42, "design": "table1", "levels": {"coupling_percent": 25, "snr_db": 20},
     "replicate": 3},
    {"study_seed": 1999, "design": "fig9", "levels": {"nfft": 512, "label": "hann"},
     "replicate": 9},
    {"study_seed": 18446744073709551615, "design": "x.y-z", "levels": {"gain": 0.5},
     "replicate": 1},
]
for case in cases:
    case["seed"] = str(cell_seed(case["study_seed"], case["design"], case["levels"],
                                 case["replicate"]))
    case["study_seed"] = str(case["study_seed"])
    case["identity"] = json.dumps({"design": case["design"], "levels": case["levels"],
                                   "replicate": case["replicate"]}, sort_keys=True,
                                  separators=(",", ":"))
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "seeds.json")
with open(out, "w") as f:
    json.dump(cases, f, indent=1)
    f.write("\n")
