"""Reading and writing ROS1 bags (rosbags), with errors that name the bag and what is wrong."""

from __future__ import annotations

from pathlib import Path

from rosbags.rosbag1 import Reader, Writer

from tactilepipe.atomic import atomic_path
from tactilepipe.errors import InputError
from tactilepipe.papillarray import typestore


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


def read_topics(path: str | Path, wanted: dict[str, str]) -> dict[str, tuple[list[int], list[bytes]]]:
    """Raw messages of the ``{topic: msgtype}`` present in the bag, as (bag stamps, raws).

    Topics absent from the bag are absent from the result; a topic of another type is an error.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, "bag file not found")
    if path.stat().st_size == 0:
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
