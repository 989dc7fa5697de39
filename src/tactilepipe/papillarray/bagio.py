"""Reading and writing ROS1 bags (rosbags), with errors that name the bag and what is wrong."""

from __future__ import annotations

from pathlib import Path

from rosbags.rosbag1 import Reader, Writer

from tactilepipe.core.atomic import atomic_path
from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import BAG_MAX, check_raw_file
from tactilepipe.papillarray.messages import typestore


def write_bag(path: str | Path, topics: dict[str, tuple[str, list[int], list[bytes]]]) -> None:
    """Write ``{topic: (msgtype, stamps_ns, raw_messages)}`` atomically, messages in time order."""
    store = typestore()
    with atomic_path(path) as tmp:
        tmp.unlink()  # rosbags refuses to overwrite
        with Writer(tmp) as writer:
            events = []
            for topic, (msgtype, stamps, raws) in topics.items():
                conn = writer.add_connection(topic, msgtype, typestore=store)
                events.extend((int(t), i, conn, raw) for i, (t, raw) in enumerate(zip(stamps, raws)))
            events.sort(key=lambda e: (e[0], e[2].id, e[1]))
            for stamp, _, conn, raw in events:
                writer.write(conn, stamp, raw)


def _fields(msgdef: str) -> dict[str, dict[str, str]]:
    """{section: {field: type}} of a ROS1 message definition (the main message is section "",
    each embedded type its "MSG: pkg/Type" name); comments and constants left out."""
    out: dict[str, dict[str, str]] = {"": {}}
    section = ""
    for line in msgdef.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or set(line) == {"="}:
            continue
        if line.startswith("MSG:"):
            section = line[4:].strip().split("/")[-1]
            out[section] = {}
            continue
        parts = line.split()
        if len(parts) >= 2 and "=" not in line:
            out[section][parts[1]] = parts[0].split("/")[-1]
    return out


def definition_differences(found: str, expected: str) -> list[str]:
    """How a bag's message definition differs from the expected one, field by field."""
    have, want = _fields(found), _fields(expected)
    diffs = []
    for section, fields in want.items():
        where = f"{section}." if section else ""
        got = have.get(section)
        if got is None:
            diffs.append(f"type {section} missing")
            continue
        diffs += [f"field {where}{f} missing" for f in fields if f not in got]
        diffs += [f"field {where}{f} is {got[f]}, expected {t}" for f, t in fields.items() if f in got and got[f] != t]
        diffs += [f"unexpected field {where}{f}" for f in got if f not in fields]
    return diffs


def _check_definition(path: Path, conn, store) -> None:
    expected, digest = store.generate_msgdef(conn.msgtype)
    if conn.digest == digest:
        return
    diffs = definition_differences(conn.msgdef.data if hasattr(conn.msgdef, "data") else conn.msgdef, expected)
    if diffs:
        shown = "; ".join(diffs[:6]) + (f"; {len(diffs) - 6} more" if len(diffs) > 6 else "")
        raise InputError(path, f"topic {conn.topic}: the bag's definition of {conn.msgtype} differs from the "
                               f"driver's: {shown}")


def read_topics(path: str | Path, wanted: dict[str, str]) -> dict[str, tuple[list[int], list[bytes]]]:
    """Raw messages of the ``{topic: msgtype}`` present in the bag, as (bag stamps, raws).

    Topics absent from the bag are absent from the result; a topic of another type is an error.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, "bag file not found")
    if check_raw_file(path, BAG_MAX, "ROS1 bag") == 0:
        raise InputError(path, "bag file is empty")
    out: dict[str, tuple[list[int], list[bytes]]] = {}
    try:
        with Reader(path) as reader:
            conns = []
            for conn in reader.connections:
                if conn.topic in wanted:
                    if conn.msgtype != wanted[conn.topic]:
                        raise InputError(path, f"topic {conn.topic} has type {conn.msgtype}, "
                                               f"expected {wanted[conn.topic]}")
                    # messages are decoded by the expected layout: a recording made with another
                    # definition of the type would be misread, so say which field differs
                    _check_definition(path, conn, typestore())
                    conns.append(conn)
                    out.setdefault(conn.topic, ([], []))
            # rosbags reads every connection when given none, so only ask when a topic matched
            for conn, stamp, raw in (reader.messages(connections=conns) if conns else ()):
                stamps, raws = out[conn.topic]
                stamps.append(stamp)
                raws.append(raw)
    except InputError:
        raise
    except Exception as exc:  # rosbags' ReaderError and low-level struct/IO errors on damaged bags
        raise InputError(path, f"cannot read ROS1 bag (truncated or corrupt?): {type(exc).__name__}: {exc}") from None
    return out
