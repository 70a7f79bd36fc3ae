#!/usr/bin/env python3
"""Reads a Rerun recording written by `vmt_logs::write_rrd` with the Python
`rerun-sdk` (0.36: `rerun.experimental.RrdReader`) and prints a JSON summary on stdout: the
package version, the recording and blueprint stores, and for every entity path its number of
temporal rows, whether it has static data, its timelines and its component columns.

Usage: python3 read_rrd.py FILE.rrd
Exit status 3 with a message on stderr when the `rerun-sdk` package is missing.
"""

import json
import sys

try:
    import rerun as rr
    from rerun.experimental import RrdReader
except ImportError as e:  # pragma: no cover - the message is the point
    print(
        f"the Python package `rerun-sdk` (0.36.3) is missing ({e}); install the test "
        "requirements with `python3 -m pip install -r tools/tests/requirements.txt`",
        file=sys.stderr,
    )
    sys.exit(3)


def components(chunk):
    """Component column names of a chunk, e.g. `Transform3D:translation`."""
    names = []
    for field in chunk.to_record_batch().schema:
        meta = field.metadata or {}
        kind = meta.get(b"rerun:kind", b"").decode()
        if kind == "data":
            names.append(meta.get(b"rerun:component", field.name.encode()).decode())
    return names


def scalar_samples(chunk):
    """(sim_time ns, value) pairs of a temporal chunk with a `Scalars:scalars` column."""
    rb = chunk.to_record_batch()
    names = rb.schema.names
    if chunk.is_static or "sim_time" not in names or "Scalars:scalars" not in names:
        return []
    times = rb.column(names.index("sim_time")).cast("int64").to_pylist()
    values = rb.column(names.index("Scalars:scalars")).to_pylist()
    return [(t, v[0]) for t, v in zip(times, values) if v]


def transform_samples(chunk):
    """(sim_time ns, translation, rotation axis-angle) of a temporal chunk with both
    `Transform3D:translation` and `Transform3D:rotation_axis_angle` columns."""
    rb = chunk.to_record_batch()
    names = rb.schema.names
    wanted = ["sim_time", "Transform3D:translation", "Transform3D:rotation_axis_angle"]
    if chunk.is_static or any(n not in names for n in wanted):
        return []
    times = rb.column(names.index(wanted[0])).cast("int64").to_pylist()
    moves = rb.column(names.index(wanted[1])).to_pylist()
    turns = rb.column(names.index(wanted[2])).to_pylist()
    return [(t, m[0], r[0]) for t, m, r in zip(times, moves, turns) if m and r]


def main(path):
    reader = RrdReader(path)
    recordings = reader.recordings()
    blueprints = reader.blueprints()
    entities = {}
    for chunk in reader.stream():
        e = entities.setdefault(
            chunk.entity_path,
            {"rows": 0, "static": False, "timelines": set(), "components": set(), "scalars": []},
        )
        e["scalars"].extend(scalar_samples(chunk))
        e.setdefault("transforms", []).extend(transform_samples(chunk))
        if chunk.is_static:
            e["static"] = True
        else:
            e["rows"] += chunk.num_rows
        e["timelines"].update(chunk.timeline_names)
        e["components"].update(components(chunk))
    for e in entities.values():
        moves = sorted(e.pop("transforms"), key=lambda x: x[0])
        for name, k in (("first_transform", 0), ("last_transform", -1)):
            if moves:
                t, m, r = moves[k]
                e[name] = {"time_ns": t, "translation": m, "rotation_axis_angle": r}
        samples = sorted(e.pop("scalars"))
        if samples:
            e["first_scalar"] = {"time_ns": samples[0][0], "value": samples[0][1]}
            e["last_scalar"] = {"time_ns": samples[-1][0], "value": samples[-1][1]}
        e["timelines"] = sorted(e["timelines"])
        e["components"] = sorted(e["components"])
    out = {
        "rerun_version": rr.__version__,
        "recordings": [
            {"application_id": s.application_id, "recording_id": s.recording_id} for s in recordings
        ],
        "blueprints": len(blueprints),
        "entities": entities,
        "timelines": sorted({t for e in entities.values() for t in e["timelines"]}),
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: read_rrd.py FILE.rrd")
    main(sys.argv[1])
