"""``--config FILE``: option values from a TOML file (keys are the options without ``--``),
every key and value checked against the option it stands for; the command line overrides it."""
import argparse
import os
import stat
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:                               # pragma: no cover
    import tomli as tomllib

from sdm_dolfinx.cli.common import UsageError, folder_path, nonnegative_float, positive_float, positive_int

#: keys that are not options of the run parser
SPECIAL_KEYS = ("problem", "problem-file")
#: the largest config file read (a few hundred bytes is usual; /dev/zero must not fill memory)
MAX_BYTES = 1 << 20


def read_toml(path):
    """The TOML file's table (UsageError when missing, not a regular file, larger than
    :data:`MAX_BYTES`, unreadable or not TOML)."""
    try:
        st = os.stat(path)
        if stat.S_ISDIR(st.st_mode):
            raise UsageError(f"config file {path} is a folder")
        if not stat.S_ISREG(st.st_mode):
            raise UsageError(f"config file {path} is not a regular file")
        with open(path, "rb") as fh:
            data = fh.read(MAX_BYTES + 1)
        if len(data) > MAX_BYTES:
            raise UsageError(f"config file {path} is larger than {MAX_BYTES >> 20} MB: not a configuration")
        return tomllib.loads(data.decode("utf-8"))
    except FileNotFoundError:
        raise UsageError(f"config file {path} not found") from None
    except OSError as e:
        raise UsageError(f"cannot read config file {_short(path)}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"{path}: invalid TOML: {e}") from None
    except UnicodeDecodeError:
        raise UsageError(f"{path}: not a TOML file (TOML is UTF-8 text)") from None


def _short(path, n=80):
    text = str(path)
    return text if len(text) <= n else text[:40] + "..." + text[-20:]


def load_config(path, parser, data=None):
    """Option defaults (by dest) for ``parser`` from the TOML file ``path``, every key checked."""
    data = dict(read_toml(path) if data is None else data)
    for key in SPECIAL_KEYS:
        data.pop(key, None)
    actions = {a.dest: a for a in parser._actions if a.dest not in ("help", "config", "restart") and a.option_strings}
    by_option = {a.option_strings[-1][2:]: a for a in actions.values()}
    defaults, seen = {}, {}
    for key, value in data.items():
        action = by_option.get(key) or by_option.get(key.replace("_", "-"))
        if action is None:
            raise UsageError(f"{path}: unknown key '{key}'; allowed keys: "
                             f"{', '.join(sorted(set(SPECIAL_KEYS) | set(by_option)))}")
        if action.dest in seen:
            raise UsageError(f"{path}: keys '{seen[action.dest]}' and '{key}' are the same option")
        seen[action.dest] = key
        defaults[action.dest] = _config_value(path, action, key, value)
    return defaults


def _config_value(path, action, key, value):
    """Check one TOML value against the option's argparse action; returns the value to use."""
    def bad(expected):
        return UsageError(f"{path}: key '{key}': expected {expected}, got {value!r}")
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        if not isinstance(value, bool):
            raise bad("true or false")
        # the key is the flag: `no-obstacle = true` gives what --no-obstacle gives
        return action.const if value else (not action.const)
    if isinstance(action.nargs, int) and action.nargs > 1:
        n = action.nargs
        if not (isinstance(value, list) and len(value) == n
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            raise bad(f"a list of {n} numbers")
        return [float(v) for v in value]
    kinds = getattr(action.type, "toml_types", None)      # a number or a word (--quadrature-degree)
    if kinds is not None:
        if not isinstance(value, kinds) or isinstance(value, bool):
            raise bad(action.type.toml_expected)
        try:
            return action.type(str(value))
        except argparse.ArgumentTypeError as e:
            raise UsageError(f"{path}: key '{key}': {e}") from None
    numbers = {int: (int, "an integer"), positive_int: (int, "an integer"),
               float: ((int, float), "a number"), positive_float: ((int, float), "a number"),
               nonnegative_float: ((int, float), "a number")}
    if action.type in numbers:
        kinds, expected = numbers[action.type]
        if not isinstance(value, kinds) or isinstance(value, bool):
            raise bad(expected)
        try:
            return action.type(str(value))
        except argparse.ArgumentTypeError as e:
            raise UsageError(f"{path}: key '{key}': {e}") from None
    if action.type in (Path, folder_path):
        if not isinstance(value, str):
            raise bad("a path (string)")
        try:
            return action.type(value)
        except argparse.ArgumentTypeError as e:
            raise UsageError(f"{path}: key '{key}': {e}") from None
    if not isinstance(value, str):
        raise bad("a string" + (f" among {', '.join(map(str, action.choices))}" if action.choices else ""))
    if action.choices is not None and value not in action.choices:
        raise UsageError(f"{path}: key '{key}': {value!r} is not one of {', '.join(map(str, action.choices))}")
    return value
