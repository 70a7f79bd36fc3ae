#!/usr/bin/env python3
"""Reads an MCAP file written by `vmt_logs::write_mcap` with the Python `mcap` package
and prints a JSON summary on stdout: package version, header, topics (schema, encodings, message
counts), metadata names and values, first/last log time (ns), chunk compressions, whether the
streams' and traces' messages are in log-time order and which topics follow them, the decoded
ground truth, and per topic its first and last message and the sum of each numeric field over
its messages (added one by one in file order, so that a reader summing the same values in the
same order gets the same double exactly), and the first ten messages that fail their channel's
JSON Schema (`schema_errors`, checked with the `jsonschema` package).

Usage: python3 read_mcap.py FILE.mcap
Exit status 3 with a message on stderr when the `mcap` package is missing.
"""

import json
import sys

try:
    import mcap
    from importlib.metadata import version
    from jsonschema import Draft202012Validator
    from mcap.reader import make_reader
except ImportError as e:  # pragma: no cover - the message is the point
    print(
        f"the Python package `mcap` or `jsonschema` is missing ({e}); install the test requirements with "
        "`python3 -m pip install -r tools/tests/requirements.txt`",
        file=sys.stderr,
    )
    sys.exit(3)


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        topics = {}
        for cid, ch in summary.channels.items():
            schema = summary.schemas.get(ch.schema_id)
            topics[ch.topic] = {
                "schema_name": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
                "schema": json.loads(schema.data) if schema else None,
                "message_encoding": ch.message_encoding,
                "metadata": dict(ch.metadata),
                "count": 0,
                "statistics_count": summary.statistics.channel_message_counts.get(cid, 0),
                "first": None,
                "last": None,
                "sums": {},
            }
        # Every message against its channel's JSON Schema, as Foxglove reads the fields from it.
        validators = {
            ch.topic: Draft202012Validator(json.loads(summary.schemas[ch.schema_id].data))
            for ch in summary.channels.values()
            if ch.schema_id in summary.schemas
        }
        schema_errors = []
        first_time, last_time, previous, ordered, tail = None, None, -1, True, []
        ground_truth = None
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            t = topics[channel.topic]
            t["count"] += 1
            if message.publish_time != message.log_time:
                raise SystemExit(f"publish_time != log_time on {channel.topic}")
            if channel.topic in ("/laser", "/ground_truth"):
                # Known when the job ends: written after the streams and traces.
                tail.append(channel.topic)
            elif tail:
                ordered = False
            else:
                ordered = ordered and message.log_time >= previous
                previous = message.log_time
            decoded = json.loads(message.data)
            validator = validators.get(channel.topic)
            if validator is not None and len(schema_errors) < 10:
                for e in validator.iter_errors(decoded):
                    schema_errors.append(f"{channel.topic} at {message.log_time} ns: {e.message}")
            if t["first"] is None:
                t["first"] = decoded
            t["last"] = decoded
            sums = t["sums"]
            for name, value in decoded.items() if isinstance(decoded, dict) else ():
                # bool is an int in Python; JSON numbers only. Plain additions, not sum(), which
                # compensates from Python 3.12 on.
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    sums[name] = sums.get(name, 0.0) + value
            if channel.topic == "/ground_truth":
                ground_truth = decoded
            first_time = message.log_time if first_time is None else min(first_time, message.log_time)
            last_time = message.log_time if last_time is None else max(last_time, message.log_time)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        compressions = sorted({c.compression for c in summary.chunk_indexes})
    out = {
        "mcap_version": version("mcap"),
        "profile": header.profile,
        "library": header.library,
        "topics": topics,
        "metadata": metadata,
        "metadata_names": sorted(metadata),
        "first_log_time_ns": first_time,
        "last_log_time_ns": last_time,
        "streams_in_time_order": ordered,
        "topics_after_streams": sorted(set(tail), key=tail.index),
        "statistics": {
            "message_count": summary.statistics.message_count,
            "message_start_time": summary.statistics.message_start_time,
            "message_end_time": summary.statistics.message_end_time,
        },
        "chunk_compressions": compressions,
        "ground_truth": ground_truth,
        "schema_errors": schema_errors,
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: read_mcap.py FILE.mcap")
    main(sys.argv[1])
