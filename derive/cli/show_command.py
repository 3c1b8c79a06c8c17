"""``derive show``: the command (its options, the cache, the output); the text itself is
derive.cli.show's. Light: a cache hit (derive.cli.show_cache) prints without importing SymPy."""
from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

from derive.cli import show_cache


def add_arguments(parser) -> None:
    """CLI: derive show [ARM] [--latex] [--exact]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    parser.add_argument("--exact", action="store_true", help="exact rationals instead of 6 digits")
    parser.add_argument("--full", action="store_true",
                        help="every term of every quantity (by default a matrix of over 200 terms is shown to a "
                             "stated precision, and beyond 4 joints G, P, D, N in terms of J and G)")
    parser.add_argument("--at", default=None, metavar="theta=...,dtheta=...[,e=...,de=...]",
                        help="print J, G, gravity, B, the free acceleration and the gains at this pose, and the "
                             "initial estimate dhat(0) for the tracking error e(0) and its rate e'(0) (default 0)")
    parser.add_argument("--json", metavar="FILE", type=Path, default=None,
                        help="also write the numbers show states (the sample-time limits of every form and observer "
                             "step, inputs beyond the effort limits, the payload limits) as strict JSON: "
                             "derive.cli.show_json")
    parser.add_argument("--no-cache", action="store_true",
                        help="derive and print anew, keeping nothing (by default what show printed is kept in the "
                             "user's cache folder, $DERIVE_CACHE_DIR, else platformdirs' user_cache_dir('derive'), "
                             "per arm file, the files it reads, the options and derive's code: derive.cli.show_cache)")


def run(args) -> int:
    """Print the derivation (derive.cli.show) and the sample-time limits; from the cache
    (derive.cli.show_cache) when the same inputs were shown before, unless ``--no-cache``."""
    encoding = (getattr(sys.stdout, "encoding", None) or "").lower()
    key = None if args.no_cache else show_cache.entry_key(args, encoding)
    json_path = getattr(args, "json", None)
    kept = show_cache.load(key) if key is not None and json_path is None else None
    if kept is not None:
        sys.stderr.write(kept[1])
        sys.stdout.write(kept[0])
        return 0
    err = _Tee(sys.stderr)
    with contextlib.redirect_stderr(err):
        text, d = _text(args, encoding)
        if json_path is not None:
            from derive.cli.show_json import render
            from derive.codegen.emit import write_file

            write_file(json_path, render(d))
    sys.stdout.write(text)
    if key is not None:
        show_cache.save(key, text, err.kept.getvalue())
    return 0


class _Tee:
    """stderr as it is, and a copy of what was written (kept with the output)."""

    def __init__(self, stream) -> None:
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


def _text(args, encoding: str) -> tuple[str, object]:
    """What ``derive show`` prints on stdout for ``args``, and the Derivation."""
    from derive.cli import load_cli_arm, report_warnings
    from derive.cli.show import render_latex, render_text
    from derive.control.pipeline import derive

    d = derive(load_cli_arm(args))
    report_warnings(d)
    if args.at is not None:
        from derive.cli.pose import parse_pose, pose_text

        text = pose_text(d, *parse_pose(args.at, d.n))
    elif args.latex:
        text = render_latex(d, exact=args.exact, full=args.full)
    else:
        text = render_text(d, exact=args.exact, unicode=encoding.startswith("utf"), full=args.full)
    text = text if text.endswith("\n") else text + "\n"
    if not args.latex:
        import textwrap

        from derive.control.sampling.limit_text import summary_all

        text += "\n" + textwrap.fill(f"Sample time: {summary_all(d)}", 100, subsequent_indent="  ") + "\n"
        from derive.control.effort import summary as effort_summary

        if (line := effort_summary(d)) is not None:   # stable is not tracking (issue 34 item 2)
            text += textwrap.fill(f"Inputs: {line}", 100, subsequent_indent="  ") + "\n"
        from derive.control.payload.text import summary as payload_summary

        if (line := payload_summary(d)) is not None:
            text += textwrap.fill(f"Payload: {line}", 100, subsequent_indent="  ") + "\n"
    return text, d
