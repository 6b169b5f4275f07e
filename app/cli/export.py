"""``handmocap export``: a labelled take or a session's reviewed take in a registered export format
(:mod:`core.review.export_formats`: C3D, TRC, CSV markers, joint angles as CSV, BVH, glTF).

The take is a labelled file (our labelled C3D, or any labelled C3D/TSV/TRC/CSV), ``SESSION_FOLDER:TAKE``
or ``SESSION_FOLDER --take TAKE`` (a take id or name of a session; the session is opened read-only and
nothing in it changes). The joint-angle formats (BVH, glTF) use the take's solved hands (found from its
marker names: :func:`core.model.detect_hands`); a hand that is not solved yet is solved here (layered IK on
the subject's calibrated hand when the file or session holds one, else the template), in memory only. Two
hands give one BVH file per hand (``OUT_right.bvh``, ``OUT_left.bvh``) and one glTF with both.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from handmocap.app.cli.common import (
    DeferredChoices,
    DeferredHelpFormatter,
    add_outputs,
    add_rate_argument,
    progress_printer,
)
from handmocap.core.errors import InputError


def _session_take(argument: str, take: str | None) -> tuple[Path, str] | None:
    """``(session folder, take)`` when ``argument`` names a session (``FOLDER:TAKE`` or ``FOLDER`` with
    ``--take``), None for a take file."""
    if take is not None:
        if not Path(argument).is_dir():
            raise InputError(f"--take needs a session folder, and {argument} is not a folder")
        return Path(argument), take
    folder, separator, name = argument.rpartition(":")
    if separator and folder and Path(folder).is_dir() and not Path(argument).exists():
        return Path(folder), name
    if Path(argument).is_dir():
        raise InputError(f"{argument} is a folder: name a take of the session (FOLDER:TAKE or --take TAKE)")
    return None


def _file_review(path: str, frame_rate: float | None = None):
    """The review of a labelled take file (at ``frame_rate`` Hz when given) and the subject's hand models and
    marker sets it holds."""
    from handmocap.app.cli.review import _load_review, _subject_hands
    from handmocap.core.io.labelled_c3d import subject_calibrations

    if not Path(path).is_file():
        raise InputError(f"{path}: no such take file")
    review = _load_review(path, frame_rate)
    models, marker_sets = _subject_hands(review.take.parameters, path)
    return review, models, marker_sets, subject_calibrations(review.take.parameters, path)


def _solve_missing_hands(review, models: dict, marker_sets: dict, quiet: bool) -> None:
    """Solve, in memory, every hand of ``review`` that has no solved frame (layered IK over the take), with the
    progress line."""
    from handmocap.core.workflows.resolve import solve_unsolved_hands

    with progress_printer("solving the hands for the export", review.n_frames * len(review.hands)) as line:
        solve_unsolved_hands(review, models, marker_sets, progress=None if quiet else line)


def command_export(args: argparse.Namespace) -> int:
    """``handmocap export``: write a labelled take or a session's take in the chosen format; exit 2 on bad input."""
    from handmocap.core.model import load_template
    from handmocap.core.review.export import export_review
    from handmocap.core.review.export_formats import export_format
    from handmocap.core.session import Session

    chosen = export_format(args.format)
    with ExitStack() as cleanup:
        session_take = _session_take(args.take, args.take_name)
        if session_take is None:
            review, models, marker_sets, subjects = _file_review(args.take, args.rate)
            where = args.take
        else:
            folder, take_id = session_take
            session = Session.open(folder, read_only=True)
            opened = session.open_take(take_id)
            cleanup.callback(opened.close, save=False)
            review, models, marker_sets, subjects = opened.review, {}, {}, None
            entry = opened.entry
            if entry.subject and any(s.name == entry.subject and s.model for s in session.subjects):
                model = session.load_subject_model(entry.subject)
                models[model.side] = model
            where = f"take '{entry.name}' of session {folder}"
        hand_models = {}
        if chosen.joint_angles:
            _solve_missing_hands(review, models, marker_sets, args.quiet)
            hand_models = {hand.side: models.get(hand.side) or load_template(hand.side) for hand in review.hands}
            if chosen.per_hand and args.hand is None:
                _check_hand_outputs(review, args.out, args.overwrite)
        written = export_review(review, args.out, args.format, units=args.units, up=args.up, hand=args.hand,
                                fills=not args.no_fills, models=hand_models, subjects=subjects)
    print(f"exported {where} ({review.n_frames} frames, {review.n_labels} labels) as {args.format} -> "
          f"{', '.join(str(path) for path in written)}")
    return 0


def _check_hand_outputs(review, out: str, overwrite: bool) -> None:
    """Check the per-hand files (``OUT_right.bvh``...) of a take with two solved hands before writing."""
    from handmocap.app.cli.common import check_output
    from handmocap.core.review.export import per_hand_path

    solved = [hand for hand in review.hands if np.isfinite(hand.joint_angles).all(axis=1).any()]
    if len(solved) > 1:
        for hand in solved:
            check_output(per_hand_path(out, hand.side), overwrite)


def _formats() -> tuple:
    """The registered export formats."""
    import handmocap.core.review  # noqa: F401  (registers the built-in export formats)
    from handmocap.core.review.export_formats import export_formats

    return export_formats()


def _format_names() -> tuple[str, ...]:
    """The names of the registered export formats."""
    import handmocap.core.review  # noqa: F401  (registers the built-in export formats)
    from handmocap.core.review.export_formats import export_format_names

    return export_format_names()


def _names(test: Callable[[Any], bool]) -> str:
    """The names of the registered export formats that pass ``test``, comma-separated."""
    return ", ".join(chosen.name for chosen in _formats() if test(chosen))


def _description() -> str:
    return ("Formats: " + "; ".join(
        f"{chosen.name} ({chosen.label}, {' or '.join(chosen.suffixes)}"
        + (")" if chosen.axes else f"; always {chosen.units}, {chosen.up.upper()} up)") for chosen in _formats())
        + ". OpenSim: --units m --up y; Blender: --units m --up y; MotionBuilder: --units cm --up y.")


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``export`` to the ``handmocap`` parser. Its texts name the registered formats and are read when the
    help is shown (:class:`DeferredHelpFormatter`), its formats when ``--format`` is given."""
    export = commands.add_parser(
        "export", help=lambda: f"export a labelled take or a session's take as {_names(lambda chosen: True)}",
        description=_description, formatter_class=DeferredHelpFormatter)
    export.add_argument("take", metavar="TAKE", help="labelled take file, or SESSION_FOLDER:TAKE (id or name), or "
                        "SESSION_FOLDER with --take")
    add_rate_argument(export)
    export.add_argument("--take", dest="take_name", metavar="NAME", help="the take (id or name) of the session")
    export.add_argument("--format", required=True, metavar="FORMAT",
                        choices=DeferredChoices(_format_names),
                        help=lambda: f"{_names(lambda chosen: not chosen.joint_angles)}: labelled points; "
                        f"{_names(lambda chosen: chosen.joint_angles)}: the solved hands")
    export.add_argument("--out", required=True, metavar="FILE", help="the file to write")
    export.add_argument("--units", choices=["mm", "cm", "m"],
                        help=lambda: f"{_names(lambda chosen: chosen.axes)} lengths (default mm)")
    export.add_argument("--up", choices=["y", "z"],
                        help=lambda: f"{_names(lambda chosen: chosen.axes)} up axis (default z, the lab frame)")
    export.add_argument("--hand", choices=["right", "left"],
                        help=lambda: f"{_names(lambda chosen: chosen.joint_angles)}: that hand only (default: every "
                        f"hand: with two, a file per hand for {_names(lambda chosen: chosen.per_hand)} (FILE_right.bvh "
                        "and FILE_left.bvh), one file with both for the others)")
    export.add_argument("--no-fills", action="store_true",
                        help=lambda: f"{_names(lambda chosen: not chosen.joint_angles)}: leave filled samples out")
    export.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(export, "out")
    export.set_defaults(handler=command_export)
