"""Config's reading layer, above limits: a YAML file with its line numbers, and the one-line
ConfigErrors (file, key path, line) that mesh_files and the two schemas raise through it."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import yaml
from pydantic import ValidationError

from .limits import NAME_PATTERN

MAX_YAML_NODES = 1_000_000  # after aliases are expanded: a few alias levels can mean billions


class ConfigError(Exception):
    """Bad input: the message is one line naming file, key path and, where known, line."""


def check_name(kind: str, name: str) -> str:
    """A scene or technique name becomes a folder and file name under ``--out``: only
    ``NAME_PATTERN`` names, so none can climb out of it, hide, or carry markup."""
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise ValueError(f"{kind} name {name!r}: use letters, digits, '_', '-' and '.' (not "
                         "first), at most 64 characters")
    return name


def _line_of(node, path: tuple) -> int | None:
    """Line (1-based) of the deepest YAML node reachable along a pydantic error location."""
    line = None
    for key in path:
        if node is None:
            break
        line = node.start_mark.line + 1
        if isinstance(node, yaml.MappingNode):
            node = next((v for k, v in node.value if k.value == str(key)), None)
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
        elif isinstance(node, yaml.SequenceNode):
            continue  # a discriminator tag in the location, not a YAML key
        else:
            node = None
    if node is not None:
        line = node.start_mark.line + 1
    return line


def _clean_loc(loc: tuple, node) -> tuple:
    """The key path of a pydantic error location in the YAML document. Parts that are not keys
    or indices of the document (pydantic's union and discriminator tags such as 'box',
    'function-after[...]', 'bool') are dropped; a missing key at the end is kept."""
    out = []
    for i, part in enumerate(loc):
        last = i == len(loc) - 1
        if isinstance(node, yaml.MappingNode):
            child = next((v for k, v in node.value if k.value == str(part)), None)
            if child is not None or (last and "[" not in str(part)):
                out.append(part)
                node = child
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int):
            out.append(part)
            node = node.value[part] if part < len(node.value) else None
        elif node is None and "[" not in str(part):
            out.append(part)
    return tuple(out)


def format_validation_error(path: Path, err: ValidationError, root_node, prefix=()) -> str:
    first = err.errors()[0]
    loc = _clean_loc(prefix + tuple(first["loc"]), root_node)
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    elif first["type"] == "missing":
        msg = "required key is missing"
    field, sep, rest = msg.partition(": ")
    path_in_model = field.split(".")
    if sep and all(p.isidentifier() or p.isdigit() for p in path_in_model):  # a model-level
        # check naming its key, or a key below it (``0.name`` of a list)
        loc, msg = loc + tuple(int(p) if p.isdigit() else p for p in path_in_model), rest
    keypath = ".".join(str(p) for p in loc)
    line = _line_of(root_node, loc)
    where = f"{path}:{line}" if line else str(path)
    more = len(err.errors()) - 1
    return f"{where}: {keypath}: {msg}" + (f" (and {more} more)" if more else "")


_FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
               (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
               (stat.S_ISBLK, "a block device"))


def check_regular_file(path: Path) -> None:
    """An OSError (no such file, ...) or a ValueError unless ``path`` is a regular file, found
    with stat before anything opens it: opening a FIFO with no writer blocks for ever, and a
    device can stream without end."""
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in _FILE_KINDS if test(mode)), "a special file")
        raise ValueError(f"not a regular file: it is {kind}")


def read_yaml(path: Path):
    """Parse a YAML file; return (data, root node). Errors are ConfigErrors: a file that is not
    a regular file, not UTF-8 text, not YAML, repeats a key in one mapping, or expands past
    ``MAX_YAML_NODES``."""
    try:
        check_regular_file(path)
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not a text file (byte {e.object[e.start]:#04x} at offset "
                          f"{e.start} is not UTF-8)") from None
    except ValueError as e:  # after UnicodeDecodeError, one of its kinds
        raise ConfigError(f"{path}: {e}") from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from None
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        _check_nodes(path, node)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f":{mark.line + 1}" if mark else ""
        problem = " ".join(str(getattr(e, "problem", None) or e).split())
        raise ConfigError(f"{path}{line}: not valid YAML: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid YAML: nested too deeply") from None
    return data, node


def _check_nodes(path: Path, root) -> None:
    """Duplicate keys (YAML loaders keep the last silently), aliases that contain themselves,
    and alias expansion past ``MAX_YAML_NODES`` (a few nested aliases can stand for billions of
    nodes) are errors. Merge keys (``<<: *anchor``) may be overridden: that is their purpose."""
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()

    def expanded(node) -> int:
        if id(node) in sizes:
            return sizes[id(node)]
        if id(node) in open_nodes:
            raise ConfigError(f"{path}:{node.start_mark.line + 1}: an alias refers to the node "
                              "that contains it")
        open_nodes.add(id(node))
        total = 1
        if isinstance(node, yaml.MappingNode):
            first_line: dict[tuple, int] = {}
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.tag != "tag:yaml.org,2002:merge":
                    line = key.start_mark.line + 1
                    if (key.tag, key.value) in first_line:
                        raise ConfigError(f"{path}:{line}: key {key.value!r} is given twice "
                                          f"in one mapping, at lines "
                                          f"{first_line[key.tag, key.value]} and {line}")
                    first_line[key.tag, key.value] = line
                total += expanded(key) + expanded(value)
        elif isinstance(node, yaml.SequenceNode):
            total += sum(expanded(child) for child in node.value)
        open_nodes.discard(id(node))
        sizes[id(node)] = total
        if total > MAX_YAML_NODES:
            raise ConfigError(f"{path}:{node.start_mark.line + 1}: the aliases in this value "
                              f"expand to more than {MAX_YAML_NODES:,} values")
        return total

    if root is not None:
        expanded(root)


def key_error(path: Path, node, loc: tuple, message: str) -> ConfigError:
    """A ConfigError for a key path found invalid after schema validation."""
    line = _line_of(node, loc) if node is not None else None
    where = f"{path}:{line}" if line else str(path)
    return ConfigError(f"{where}: {'.'.join(map(str, loc))}: {message}")
