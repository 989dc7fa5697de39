"""YAML read with its alias expansion bounded.

An alias (``*a``) stands for the whole node its anchor (``&a``) names, so nested anchors grow
geometrically: a 600-byte file can stand for a billion nodes ("billion laughs"). PyYAML builds
them all, and so does every reader after it that walks the result (the schema check, a deep copy,
Snakemake's config merge), until the machine runs out of memory. Here the event stream is read
first, without building anything, counting the nodes each anchor stands for; a document that would
expand past ``MAX_NODES`` is refused, naming the file.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tactilepipe.core.errors import ConfigError

# params.yaml is about 1,300 nodes (keys count), dvc.yaml about 700, a dvc.lock a few thousand; normal
# anchor use (a block repeated a few times) adds little. 200,000 is far above any of them and loads
# in a fraction of a second; a billion-laughs file passes it within a few levels of nesting.
MAX_NODES = 200_000


def expanded_nodes(text: str, source: str, limit: int = MAX_NODES) -> int:
    """The number of nodes ``text`` stands for with every alias expanded (each document's, summed);
    ConfigError naming ``source`` as soon as it passes ``limit``, or on an alias of a node that
    contains it (a recursive structure has no finite expansion)."""
    total, sizes, open_nodes = 0, {}, []          # open_nodes: [anchor, nodes so far] of each open collection
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, yaml.DocumentStartEvent):
                sizes = {}
                continue
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                open_nodes.append([event.anchor, 1])
                continue
            if isinstance(event, yaml.AliasEvent):
                if any(anchor == event.anchor for anchor, _ in open_nodes):
                    raise ConfigError(f"{source}: alias *{event.anchor} refers to a node that contains it "
                                      f"(line {event.start_mark.line + 1}): a recursive structure is not a parameter")
                size = sizes.get(event.anchor, 1)     # an undefined alias: the loader names it
            elif isinstance(event, yaml.ScalarEvent):
                size = 1
                if event.anchor:
                    sizes[event.anchor] = size
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                anchor, size = open_nodes.pop()
                if anchor:
                    sizes[anchor] = size
            else:
                continue
            if open_nodes:
                open_nodes[-1][1] += size
                size = open_nodes[-1][1]
            else:
                total += size
            if size > limit or total > limit:
                raise ConfigError(f"{source}: its anchors and aliases expand to more than {limit:,} nodes "
                                  f"(at line {event.start_mark.line + 1}): refused before loading")
    except yaml.YAMLError:
        return total                              # malformed: the loader that follows names the problem
    return total


def load_yaml_text(text: str, source: str, limit: int = MAX_NODES):
    """``yaml.safe_load(text)`` once its expansion is known to stay within ``limit`` nodes."""
    expanded_nodes(text, source, limit)
    return yaml.safe_load(text)


def load_yaml_file(path: str | Path, limit: int = MAX_NODES):
    """``yaml.safe_load`` of the file at ``path``, its expansion bounded (ConfigError naming it)."""
    return load_yaml_text(Path(path).read_text(), str(path), limit)


def check_yaml_file(path: str | Path, limit: int = MAX_NODES) -> None:
    """Refuse the file at ``path`` if its expansion passes ``limit`` nodes (ConfigError naming it);
    a file that is missing or malformed is left for its reader to name."""
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError):
        return
    expanded_nodes(text, str(path), limit)
