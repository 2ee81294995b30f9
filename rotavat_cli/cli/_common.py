"""Shared CLI plumbing: the two consoles (results on stdout, diagnostics on stderr), the one error
handler, progress, JSON output."""

from __future__ import annotations

import importlib
import json
import os
import shlex
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from ..settings.config import load_config, merge_config
from ..errors import InputError
from ..settings.limits import Limits
from ..settings.limits import configure as configure_limits
from ..settings.option_rules import Rule
from ..files.outputs import as_typed, beside, imported_output
from ..plain import to_plain
from ..sequence import Sequence, is_sequence_dir, open_sequence
from ._run import ARGV_KEY, JSON_PRINTED_KEY, current_context

console = Console(stderr=True)  # diagnostics: progress, notes, warnings, errors
results = Console()  # what a command produces for a human (tables, its summary): `rotavat info SEQ > f.txt` keeps it

ConfigOpt = Annotated[Path | None, typer.Option("--config", help="YAML file overriding configs/default.yaml (flags override it).", dir_okay=False)]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar, no notes and no summary or table on stdout; warnings and errors still go to stderr.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a machine-readable JSON result on stdout (implies no progress bar).")]
FromOpt = Annotated[str | None, typer.Option("--from", help="Read the input in an HPS tool's own format, converted on the fly (formats: see `rotavat import --help`).")]
ImageSizeOpt = Annotated[tuple[int, int] | None, typer.Option(help="With --from: original image width and height (px), for formats that do not store it.")]
ForceOpt = Annotated[bool, typer.Option("--force", help="Replace an existing output that rotavat did not write (never an input).")]
SmplModelOpt = Annotated[Path | None, typer.Option(help="With --from: SMPL/SMPL-X model (.npz, or the official .pkl) to pose parameter-only formats.", dir_okay=False)]
FocalMmOpt = Annotated[float | None, typer.Option("--focal-mm", help="The camera's known focal length as a 35 mm-equivalent focal (mm, as phones and EXIF state it), converted at the sequence's image size: f_px = MM / 43.27 * sqrt(W^2 + H^2). Not with --focal.")]


def _default_text(value: Any, flag: str) -> str:
    """How --help shows a default: a flag pair by the flag that is on, lists comma-separated, null as none."""
    if isinstance(value, bool) and "/" in flag:
        on, off = flag.split("/")
        return on if value else off
    if value is None:
        return "none"
    if isinstance(value, (list, tuple)):
        return " ".join(_default_text(v, "") for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


# Below this terminal width, --help lists options click's plain way (name, then its help over the rest of
# the line): rich's panel gives each option's help ~17 columns of 80 and cuts it.
RICH_HELP_MIN_COLUMNS = 120


def _plain_when_narrow(command: Any) -> None:
    """Make ``command``'s --help plain text on a terminal narrower than :data:`RICH_HELP_MIN_COLUMNS`."""
    rich_format = command.format_help

    def format_help(ctx: Any, formatter: Any) -> None:
        if shutil.get_terminal_size((80, 24)).columns >= RICH_HELP_MIN_COLUMNS:
            return rich_format(ctx, formatter)
        texts = [(p, p.help) for p in command.params if getattr(p, "help", None)]
        help_text, mode = command.help, command.rich_markup_mode
        try:  # the stored help is escaped for rich markup: plain text shows it as written
            for p, text in texts:
                p.help = text.replace("\\[", "[")
            command.help = help_text.replace("\\[", "[") if help_text else help_text
            command.rich_markup_mode = None  # typer then formats as click does
            return rich_format(ctx, formatter)
        finally:
            for p, text in texts:
                p.help = text
            command.help, command.rich_markup_mode = help_text, mode

    command.format_help = format_help


def polish_help(command: Any, section: dict | None, rules: dict[str, Rule] | None = None) -> None:
    """Make a command's --help read as users expect (once per command).

    Help text is plain text (``pip install 'rotavat[fast]'`` keeps its brackets), flags show no
    type, arguments show their name (SEQ), an option of a few names lists them and a bounded one its
    range (``rules``: config key -> :class:`~rotavat_cli.settings.option_rules.Rule`, the options class's own),
    and every option shows its default: the packaged
    config's value for options read from ``section`` (a flag left unset takes it), else the
    command's own default.
    """
    if getattr(command, "_rotavat_polished", False):
        return
    command._rotavat_polished = True
    _plain_when_narrow(command)
    if command.help:
        command.help = escape(command.help)
    from_config, names, spans = {}, {}, {}
    for key, value in (section or {}).items():
        if not isinstance(value, dict):
            flag = _flag_name(key)
            from_config[flag.split("/")[0]] = _default_text(value, flag)
            rule = (rules or {}).get(key)
            if rule is not None and rule.names:
                names[flag] = "|".join(rule.names)
            elif rule is not None and rule.describe():
                spans[flag] = rule.describe()
    for param in command.params:
        if getattr(param, "help", None):
            param.help = escape(param.help)
        if param.param_type_name == "argument":
            param.metavar = param.name.upper() + ("..." if param.nargs != 1 else "")
            # the usage line too: typer writes a required argument as {seq} (its private hook, per instance)
            param._usage_display_name = lambda metavar=param.metavar, required=param.required: (
                metavar if required else f"[{metavar}]")
            continue
        if getattr(param, "is_flag", False):
            param.metavar = ""  # a switch: no value to type
        elif any(opt in names for opt in param.opts):
            param.metavar = next(names[opt] for opt in param.opts if opt in names)
        shown = next((from_config[opt] for opt in param.opts if opt in from_config), None)
        if shown is None and param.default not in (None, False, ()) and not getattr(param, "is_flag", False):
            shown = _default_text(param.default, "")
        if shown in ("none", "False") or (shown == "True" and getattr(param, "is_flag", False)):
            shown = None  # unset means "not given" (its help says what then); a lone switch is off unless given
        span = next((spans[opt] for opt in param.opts if opt in spans), None)
        span = _own_range(param, span)
        if span is not None and param.help is not None:
            param.help = f"{param.help} \\[{escape(span)}]"
        if shown is not None and param.help is not None:
            param.help = f"{param.help} \\[default: {escape(shown)}]"


def _own_range(param: Any, span: str | None) -> str | None:
    """The range --help shows for ``param``, once: ``span`` (its config rule's), else the option's own bounds
    (``min=``/``max=``) written the same way (``>= 0``, ``0..1``); typer's second copy of it (``[x>=0]`` after
    the default, ``<int range>`` as its type) is turned off."""
    own = getattr(param, "_get_number_range_help_str", None)
    if own is None or not own():
        return span
    if span is None:
        low, high = getattr(param, "min", None), getattr(param, "max", None)
        span = Rule(low=low, high=high, open_low=bool(getattr(param, "min_open", False))).span()
    param._get_number_range_help_str = lambda: None  # per instance, as typer calls it
    if param.metavar is None:
        bare = getattr(param, "bare_type", None)
        param.metavar = f"<{bare()}>" if bare is not None else None  # the type as other numbers show it, not "<int range>"
    return span


def polish_command_help(command: Any, section: str) -> None:
    """:func:`polish_help` with the packaged defaults and the rules of config section ``section`` ("" for none)."""
    polish_help(command, load_config(None).get(section) if section else None,
                section_rules(section) if section else None)


def config_for(config_file: Path | None, section: str, **flags: Any) -> dict:
    """Effective options of one config section: defaults < --config FILE < flags (None = unset).

    Also puts the merged config's ``limits`` in force for this process (and the workers it forks).
    A flag's bad value is reported under the flag's name (``--size``), not its config key.
    """
    return use_config(config_file, {section: flags})[section]


# Flags named otherwise than their config key less its unit (focal_px -> --focal, box_depth_m -> --box-depth).
_FLAG_NAMES = {"estimate_roll": "--roll/--no-roll", "person_height_sd_m": "--height-sd", "threshold_px": "--threshold-px",
               "estimate_focal": "--estimate-focal", "lens_distortion": "--lens"}


def _flag_name(key: str) -> str:
    """The command-line flag that sets config key ``key`` of a section."""
    if key in _FLAG_NAMES:
        return _FLAG_NAMES[key]
    for unit in ("_px", "_deg", "_m"):
        if key.endswith(unit):
            key = key[: -len(unit)]
            break
    return "--" + key.replace("_", "-")


def check_focal_flags(focal_px: float | None, focal_mm: float | None) -> None:
    """InputError when both --focal and --focal-mm are given: each fixes the focal length."""
    if focal_px is not None and focal_mm is not None:
        raise InputError("--focal and --focal-mm both fix the focal length: give one, not both")


def focal_flag_wins(section: dict, focal_px: float | None, focal_mm: float | None) -> dict:
    """A merged ``calibrate`` section in which the focal a flag gave (--focal, or --focal-mm) replaces the config
    file's other focal key (flags override the file: ``calibrate.focal_mm`` then no longer applies, and back)."""
    check_focal_flags(focal_px, focal_mm)
    if focal_px is not None:
        return {**section, "focal_mm": None}
    return {**section, "focal_px": None} if focal_mm is not None else section


def use_config(config_file: Path | None, overrides: dict | None = None) -> dict:
    """The merged config (defaults < --config FILE < overrides: flags by section, None = unset), its
    ``limits`` put in force for this process and the workers it forks.

    Each value of the sections in use is checked against its options class's rules
    (:func:`section_rules`): a file's bad value is reported under the file and its key, a flag's under
    the flag's name (``--size``), not its config key."""
    config = load_config(config_file)
    sections = [*(overrides or {}), "limits"]
    if config_file is not None:
        for section in sections:
            _check_section(config[section], section_rules(section), f"{config_file}: key '{section}.", "'")
    for section, flags in (overrides or {}).items():
        for key, value in flags.items():
            if value is not None:
                try:
                    config = merge_config(config, {section: {key: value}}, _flag_name(key))
                except InputError as exc:
                    raise InputError(str(exc).replace(f" key '{section}.{key}'", "", 1)) from None
                _check_section({key: value}, section_rules(section), f"{_flag_name(key)}:", "", name_key=False)
    configure_limits(Limits.from_config(config.get("limits")))
    return config


def _check_section(values: dict, rules: dict[str, Rule], before: str, after: str, name_key: bool = True) -> None:
    """InputError ``{before}{key}{after} {problem}`` for a value of ``values`` (nested: ``grid.steps``)
    that its rule refuses; ``name_key=False`` leaves the key out (a flag names it already)."""
    flat = {f"{key}.{sub}": v for key, value in values.items() if isinstance(value, dict) for sub, v in value.items()}
    flat.update({key: value for key, value in values.items() if not isinstance(value, dict)})
    for key, value in flat.items():
        problem = rules[key].problem(value) if key in rules else None
        if problem is not None:
            raise InputError(f"{before}{key if name_key else ''}{after} {problem}")


# config section -> the module and the name of what checks its keys (an options class's RULES, or a table),
# imported when a command that reads the section runs
_SECTION_RULES = {
    "calibrate": ("calibration.options", "SECTION_RULES"), "align": ("alignment.options", "AlignOptions.RULES"),
    "eval": ("metrics.evaluate", "EvalOptions.RULES"), "render": ("render.sequences", "FigureOptions.RULES"),
    "view": ("view.recording", "ViewOptions.RULES"), "synth": ("synth.scene", "SynthOptions.RULES"),
    "batch": ("batch.plan", "BatchOptions.RULES"), "limits": ("settings.limits", "RULES"),
    "export": ("exchange.options", "ExportOptions.RULES"),
}


def section_rules(section: str) -> dict[str, Rule]:
    """What each key of a config section may be: the rules of the options class that reads it ({} for none)."""
    if section not in _SECTION_RULES:
        return {}
    module, name = _SECTION_RULES[section]
    found: Any = importlib.import_module(f"rotavat_cli.{module}")
    for part in name.split("."):
        found = getattr(found, part)
    return found


@contextmanager
def input_sequence(path: Path, fmt: str | None, image_size: tuple[int, int] | None = None,
                   smpl_model: Path | None = None, read_camera: bool = True, quiet: bool = False) -> Iterator[Sequence]:
    """Open a contract sequence, or with ``fmt`` read an HPS tool's output as one, each frame converted
    when it is read (nothing written: ``rotavat_cli.formats.imported_sequence``).

    Entries of OBJ frame folders that are not people's OBJ files are reported (never silently skipped);
    what converting found (the warnings ``rotavat import`` prints) is printed once, after the command.
    """
    if fmt is None:
        check_sequence_path(path)
        seq = open_sequence(path, read_camera=read_camera)
        warn_ignored(seq)
        yield seq
        return
    from ..formats.convert import imported_sequence
    from ..formats.registry import available_formats

    if fmt not in available_formats():
        raise InputError(f"unknown format '{fmt}' for --from (known: {', '.join(available_formats())})")
    with imported_sequence(path, fmt, image_size=image_size, smpl_model=smpl_model, read_camera=read_camera) as seq:
        yield seq
        for warning in seq.warnings:
            warn(str(warning))


def check_sequence_path(path: Path) -> None:
    """Nothing when ``path`` may be a sequence directory; else the one-line refusal that says what it is and
    the command that reads it (:func:`not_a_sequence`). Commands call it on a SEQ read without ``--from``
    before anything else looks at the path (``input_sequence`` does)."""
    refusal = not_a_sequence(path)
    if refusal is not None:
        raise refusal


def not_a_sequence(path: Path) -> InputError | None:
    """The refusal of a file, or a folder of an HPS tool's files, given where a sequence directory is read,
    naming what it is and the command that reads it (None for a sequence directory, a missing path, and a
    folder of no frames and no tool's output: ``open_sequence`` names those).

    An HPS tool's output (recognised by the sniffers ``rotavat import`` detects formats with:
    :func:`rotavat_cli.formats.registry.detect_format`) is named with the two commands that read it: the
    user's own command line with ``--from FMT`` (``--gt-from`` for eval's ``--gt``; calibrate also gets the
    ``--out`` it needs then), when ``--from`` reads that argument, and ``rotavat import --from FMT SRC OUT``.
    A contract frame (``000000.npz`` of a sequence) is named with its folder; any other file says what it is.
    """
    if not path.is_file() and (not path.is_dir() or is_sequence_dir(path)):
        return None  # the readers' modules are imported only to name what is not a sequence
    from ..formats.file_kinds import file_kind
    from ..formats.registry import detect_format
    from ..formats.tools import FORMATS, TOOL_NAMES

    if path.is_dir():  # a folder of a tool's files (AGORA's, ...), not of frames
        fmt = detect_format(path)
        if fmt is None:
            return None
        read = _command_line(path, None, fmt)
        convert = shlex.join(["rotavat", "import", "--from", fmt, str(path), str(imported_output(path, "_seq"))])
        return InputError(f"{path}: a folder of {TOOL_NAMES[fmt]} output, not a sequence directory (a directory of "
                          "frames); " + (f"read it as it is: {read}, or " if read else "")
                          + f"convert it once into a sequence: {convert}")
    fmt = detect_format(path)
    if fmt is None:
        folder = path.parent
        if path.suffix == ".npz" and is_sequence_dir(folder):
            again = _command_line(path, folder)
            return InputError(f"{path}: a frame of a sequence, not a sequence directory: the sequence is its folder"
                              + (f" ({again})" if again else f" ({folder})"))
        kind = file_kind(path)  # a JSON file, an image, a video, ...
        what = f"{kind}, not a sequence directory" if kind else "not a directory"
        return InputError(f"{path}: {what} (a sequence is a directory of frames), nor an output rotavat recognises "
                          f"of the HPS tools it reads ({', '.join(FORMATS)}: rotavat import --help)")
    convert = shlex.join(["rotavat", "import", "--from", fmt, str(path), str(imported_output(path, ""))])
    read = _command_line(path, None, fmt)
    return InputError(f"{path}: a file, not a sequence directory (a directory of frames): it is {TOOL_NAMES[fmt]} "
                      "output; " + (f"read it as it is: {read}, or " if read else "")
                      + f"convert it once into a sequence: {convert}")


# Commands whose --from reads only their first sequence argument (the other rows are sequence directories), and
# those whose --from reads a folder of a tool's outputs, never one (batch: ROOT is a folder).
_FROM_READS_FIRST = ("render", "view")
_FROM_READS_FOLDERS = ("batch",)


def _command_line(path: Path, replacement: Path | None, fmt: str | None = None) -> str | None:
    """The running command's line as the user gave it, with ``path`` replaced by ``replacement`` or, with
    ``fmt``, read with ``--from fmt`` (``--gt-from`` for eval's --gt); None outside a run, or when no such
    flag of the command reads ``path`` alone."""
    ctx = current_context()
    argv = None if ctx is None else ctx.meta.get(ARGV_KEY)
    if not argv:
        return None
    if replacement is not None:
        return shlex.join(["rotavat", *(str(replacement) if Path(a) == path else a for a in argv)])
    opts = {opt for param in ctx.command.params for opt in getattr(param, "opts", ())}
    flag = None
    for name, value in ctx.params.items():
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        if not any(isinstance(v, Path) and v == path for v in values):
            continue
        if name == "gt":
            flag = "--gt-from" if "--gt-from" in opts and ctx.params.get("gt_from") is None else None
        elif "--from" in opts and ctx.params.get("from_") is None and (
                len(values) == 1 or (ctx.info_name in _FROM_READS_FIRST and values[0] == path)):
            flag = "--from"
        break
    if flag is None or ctx.info_name in _FROM_READS_FOLDERS:
        return None
    line = ["rotavat", *argv, flag, fmt]
    if ctx.info_name == "calibrate" and ctx.params.get("out") is None:  # with --from, calibrate writes where told
        line += ["--out", str(imported_output(path, "_camera.yaml"))]
    return shlex.join(line)


def default_output(src: Path, suffix: str, fmt: str | None) -> Path:
    """Where a command writes when no ``--out`` is given: beside a contract sequence (``SEQ<suffix>``), but in
    the current folder for an HPS tool's own output read with ``--from`` (never into the user's data folder)."""
    return imported_output(src, suffix) if fmt is not None else as_typed(beside(src, suffix))


def warn_ignored(seq: Sequence) -> None:
    """One warning line for the entries of OBJ frame folders that were ignored, with the first few."""
    if seq.ignored:
        shown = "; ".join(seq.ignored[:3]) + (f"; and {len(seq.ignored) - 3} more" if len(seq.ignored) > 3 else "")
        warn(f"{seq.path}: ignored {len(seq.ignored)} entries of OBJ frame folders ({shown})")


def progress_enabled(quiet: bool, as_json: bool) -> bool:
    """Live bars only on a real interactive terminal: never with --quiet/--json or in CI.

    rich treats FORCE_COLOR as "a terminal", so the stream itself must be a tty too, and a
    ``CI`` environment variable turns bars off (CI logs get the summary lines only).
    """
    if quiet or as_json or os.environ.get("CI") or not console.is_interactive:
        return False
    try:
        return bool(console.file.isatty())
    except (AttributeError, ValueError):
        return False


@contextmanager
def progress_bar(description: str, total: int | None, enabled: bool) -> Iterator[Any]:
    """A rich progress bar yielding an ``advance()`` callable."""
    progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                        console=console, disable=not enabled, transient=True)
    with progress:
        task = progress.add_task(description, total=total)
        yield lambda n=1: progress.advance(task, n)


def print_json(data: Any) -> None:
    """Write ``data`` as JSON to stdout (the command's result: an error after it adds no JSON object of its own)."""
    typer.echo(json.dumps(to_plain(data), indent=2))
    ctx = current_context()
    if ctx is not None:
        ctx.meta[JSON_PRINTED_KEY] = True


def info(message: str, quiet: bool) -> None:
    """A note (what rotavat decided, what it did) on stderr unless --quiet."""
    if not quiet:
        console.print(message, highlight=False)


def warn(message: str) -> None:
    """A warning on stderr, one line, even under --quiet (it says something is wrong); ``message`` is plain text."""
    console.print(f"[yellow]warning:[/] {escape(message)}", highlight=False, soft_wrap=True)


def report(message: Any, quiet: bool) -> None:
    """A result for a human (a table, the command's summary line) on stdout unless --quiet."""
    if not quiet:
        results.print(message, highlight=False, soft_wrap=isinstance(message, str))
