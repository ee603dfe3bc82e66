"""Config's reading layer, above limits: a YAML file with its line numbers, and the one-line
ConfigErrors (file, key path, line) that mesh_files and the two schemas raise through it."""

from __future__ import annotations

import copy
import os
import stat
from collections import OrderedDict
from pathlib import Path

import yaml
from pydantic import ValidationError

from .limits import NAME_PATTERN
from ..machine.file_stamps import stamp

MAX_YAML_NODES = 1_000_000  # after aliases are expanded: a few alias levels can mean billions


class ConfigError(Exception):
    """Bad input: the message is one line naming file, key path and, where known, line.
    ``more``: further problems of the same input, one line each (the command prints them
    after the first)."""

    def __init__(self, message: str, more: tuple[str, ...] = ()):
        super().__init__(message)
        self.more = tuple(more)


def check_name(kind: str, name: str) -> str:
    """A scene or technique name becomes a folder and file name under ``--out``: only
    ``NAME_PATTERN`` names, so none can climb out of it, hide, or carry markup."""
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise ValueError(f"{kind} name {name!r}: use letters, digits, '_', '-' and '.' (not "
                         "first), at most 64 characters")
    return name


def line_of(node, path: tuple) -> int | None:
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


MAX_LISTED_ERRORS = 5  # a file's errors listed, each with its line; the rest counted


def _fields_at(model, loc: tuple) -> list[str]:
    """The keys the schema allows at ``loc`` below ``model`` (a pydantic model class), walking
    fields, dict values, list items and union members (pydantic's tags in ``loc`` name the
    member); [] where the walk finds no model."""
    import typing

    from pydantic import BaseModel

    def members(annotation) -> list:
        origin = typing.get_origin(annotation)
        if origin is typing.Annotated:
            return members(typing.get_args(annotation)[0])
        if origin is not None and origin not in (list, dict, tuple):  # a union
            return [m for a in typing.get_args(annotation) for m in members(a)]
        return [annotation]

    candidates = [model]
    for part in loc:
        following = []
        for c in candidates:
            if isinstance(c, type) and issubclass(c, BaseModel):
                field = c.model_fields.get(str(part))
                if field is not None:
                    following += members(field.annotation)
                elif any(getattr(f.annotation, "__args__", ()) == (part,) for f in
                         c.model_fields.values()):
                    following.append(c)  # a union tag naming this member (shape: box)
            elif typing.get_origin(c) in (list, tuple, dict):
                args = typing.get_args(c)
                following += members(args[-1] if args else None)
        candidates = [c for c in following if c is not None] or [
            c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)
            and "[" in str(part)]  # pydantic's function-after[...] and the like
    return sorted({name for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)
                   for name in c.model_fields})


def _error_line(path: Path, error: dict, root_node, prefix: tuple,
                allowed) -> tuple[int, str, str]:
    """(sort key, key path, "file:line: key.path: message") of one pydantic error. An unknown key comes
    first, at its own line, with the closest key the schema allows there."""
    import difflib

    loc = _clean_loc(prefix + tuple(error["loc"]), root_node)
    msg = error["msg"].removeprefix("Value error, ")
    rank = 1
    if error["type"] == "extra_forbidden":
        rank, msg = 0, "unknown key"
        close = difflib.get_close_matches(str(loc[-1]), allowed(error["loc"][:-1]), n=1)
        if close:
            msg += f"; did you mean `{close[0]}`?"
    elif error["type"] == "missing":
        msg = "required key is missing"
    field, sep, rest = msg.partition(": ")
    path_in_model = field.split(".")
    if sep and all(p.isidentifier() or p.isdigit() for p in path_in_model):  # a model-level
        # check naming its key, or a key below it (``0.name`` of a list)
        loc, msg = loc + tuple(int(p) if p.isdigit() else p for p in path_in_model), rest
    keypath = ".".join(str(p) for p in loc)
    line = line_of(root_node, loc)
    where = f"{path}:{line}" if line else str(path)
    return rank, keypath, f"{where}: {keypath}: {msg}"


def validation_error(path: Path, err: ValidationError, root_node, prefix=(),
                     model=None) -> ConfigError:
    """A ConfigError listing a file's validation errors, unknown keys first, each with its line
    (up to ``MAX_LISTED_ERRORS``, then how many more); ``model``: the pydantic model validated,
    for the keys an unknown key is compared with."""
    def allowed(loc):
        return _fields_at(model, loc) if model is not None else []

    errors = [_error_line(path, e, root_node, prefix, allowed) for e in err.errors()]
    # one line a key: the branches of a union (a number or a list) each fail at the same key,
    # or below it, and the first says what is wrong
    keys, lines = [], []
    for _, keypath, text in sorted(errors, key=lambda e: e[0]):
        if not any(keypath == k or keypath.startswith(k + ".") for k in keys):
            keys.append(keypath)
            lines.append(text)
    more = len(lines) - MAX_LISTED_ERRORS
    listed = lines[:MAX_LISTED_ERRORS] + ([f"(and {more} more)"] if more > 0 else [])
    return ConfigError(listed[0], tuple(listed[1:]))


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


# libyaml's parser where PyYAML was built with it: every command reads scenes.yaml, which took
# the pure-Python parser 0.25 s (0.03 s now). The text is parsed twice, nodes then data: the
# nodes are checked before anything is built from them (aliases that expand past any memory),
# and building the data merges `<<:` keys into the nodes in place, which the check would
# then read as repeated keys.
_LIBYAML = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_yaml(path: Path):
    """Parse a YAML file; return (data, root node). Errors are ConfigErrors: a file that is not
    a regular file, not UTF-8 text, not YAML, repeats a key in one mapping, or expands past
    ``MAX_YAML_NODES``.

    A file read before and unchanged since (its device, inode, size and modification time) is
    not parsed again: the data is a copy of what it gave then, the node the same (read only).
    ``load_scene`` reads its whole scene file for each scene it builds (35 ms for scenes.yaml:
    a tenth of the technique tests' time went to parsing it again)."""
    try:
        check_regular_file(path)
        key = (str(Path(path).resolve()), stamp(path))
        if key in _parsed:
            _parsed.move_to_end(key)
            data, node = _parsed[key]
            return copy.deepcopy(data), node
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not a text file (byte {e.object[e.start]:#04x} at offset "
                          f"{e.start} is not UTF-8)") from None
    except ValueError as e:  # after UnicodeDecodeError, one of its kinds
        raise ConfigError(f"{path}: {e}") from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from None
    try:
        try:
            node = yaml.compose(text, Loader=_LIBYAML)
            data = yaml.load(text, Loader=_LIBYAML)
        except yaml.YAMLError:  # the pure-Python parser's message, the one the docs show
            node = yaml.compose(text, Loader=yaml.SafeLoader)
            data = yaml.safe_load(text)
        _check_nodes(path, node)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f":{mark.line + 1}" if mark else ""
        problem = " ".join(str(getattr(e, "problem", None) or e).split())
        raise ConfigError(f"{path}{line}: not valid YAML: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid YAML: nested too deeply") from None
    _parsed[key] = (copy.deepcopy(data), node)
    while len(_parsed) > PARSED_FILES:
        _parsed.popitem(last=False)
    return data, node


PARSED_FILES = 16  # the files read_yaml keeps parsed: a scene file, experiments, their includes
_parsed: OrderedDict = OrderedDict()  # (a file, its stamp) -> (its data, its root node)


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
    line = line_of(node, loc) if node is not None else None
    where = f"{path}:{line}" if line else str(path)
    return ConfigError(f"{where}: {'.'.join(map(str, loc))}: {message}")
