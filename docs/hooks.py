"""MkDocs hooks (mkdocs.yml ``hooks:``): the generated pages, the benchmark tables, the figures, and
the examples' checks. Everything generated is computed here at build time from derive itself, so
the site cannot drift from the code; any problem is a build error (``make docs``).

- on_pre_build: every code example checked (docs/gen/examples.py), the ``<!-- docs: run -->``
  blocks executed;
- on_files: the reference pages (commands, arm-file keys, C API) and the committed figures of
  generated/ added to the site;
- on_page_markdown: ``<!-- bench-run: SECTION -->`` replaced by that section of the last ``make bench``
  run (docs/data/bench-run.json), ``<!-- bench: NAME -->`` by that typed table of docs/data/benchmarks.json.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
for path in (str(DOCS), str(ROOT)):
    if path not in sys.path:
        sys.path.insert(0, path)

from gen import bench, capi, cli, examples, keys  # noqa: E402

# page -> its generator; figure on the site -> the committed file it is
GENERATED = {"reference/commands.md": cli.page, "reference/arm-file.md": keys.page, "reference/c-api.md": capi.page}
FIGURES = {"img/tracking_error.png": "generated/glasgow_2link/sim/tracking_error.png",
           "img/saturation_link1.png": "generated/glasgow_2link/sim/saturation/link1.png",
           "img/sweep_envelope.png": "generated/glasgow_2link/sweep/envelope.png"}


def on_pre_build(config) -> None:
    start = time.perf_counter()
    count, problems = examples.check_all()
    if problems:
        raise PluginError("code examples that no longer fit derive:\n" + "\n".join(problems))
    ran = examples.runnable()
    for block in ran:
        if (failure := examples.run_block(block)) is not None:
            raise PluginError("a documented example failed:\n" + failure)
    print(f"derive docs: {count} code examples checked, {len(ran)} run ({time.perf_counter() - start:.1f} s)",
          file=sys.stderr)


def on_files(files, config):
    for uri, make in GENERATED.items():
        try:
            content = make()
        except ValueError as exc:
            raise PluginError(str(exc)) from exc
        files.append(File.generated(config, uri, content=content))
    for uri, source in FIGURES.items():
        files.append(File.generated(config, uri, abs_src_path=str(ROOT / source)))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    try:
        return bench.substitute(markdown)
    except bench.MissingRun as exc:
        raise PluginError(f"{page.file.src_uri}: {exc.args[0]}") from exc
    except KeyError as exc:
        raise PluginError(f"{page.file.src_uri}: no benchmark table {exc} in docs/data/benchmarks.json") from exc
