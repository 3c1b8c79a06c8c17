"""Packaging: a controller of one form as a co-simulation FMU (FMI 2.0 or 3.0).

An FMU is a zip archive (FMI 3.0 section 2.5, FMI 2.0 section 2.3)::

    modelDescription.xml            variables, units, descriptions (derive.fmu.describe)
    sources/                        the generated C library, the FMI glue, the FMI headers
    sources/buildDescription.xml    FMI 3: how to compile sources/ (FMI 2: <SourceFiles>)
    binaries/<platform>/<id>.so     sources/ built with the host C compiler
    documentation/MANIFEST.json     arm file hash, options, tool versions, file hashes
    documentation/<arm file>        the arm file itself, when given

The archive is deterministic: entries sorted, fixed timestamps and modes, so
the same input gives the same bytes wherever the compiler's output is the same.
The instantiation token (FMI 3) / guid (FMI 2) is derived from a hash of the
content, never random.
"""
from __future__ import annotations

import hashlib
import io
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path

from derive.codegen.files import REALS, library_files, manifest_text
from derive.codegen.forms import DEFAULT_FORM, FORMS
from derive.codegen.kernels import OBSERVER_STEPS, ParamsMode
from derive.codegen.render import render
from derive.codegen.views import arm_view
from derive.control.pipeline import Derivation
from derive.errors import DeriveError, EmitError
from derive.fmu.describe import fmu_view

FMI_VERSIONS = (2, 3)
HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
           3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
BUILD_FLAGS = ("-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden")
_EPOCH = (1980, 1, 1, 0, 0, 0)  # the earliest time a zip entry can carry

# (sys.platform prefix, machine) -> (FMI 3 platform tuple, FMI 2 platform folder, library suffix)
PLATFORMS = {
    ("linux", "x86_64"): ("x86_64-linux", "linux64", ".so"),
    ("linux", "aarch64"): ("aarch64-linux", "", ".so"),
    ("darwin", "x86_64"): ("x86_64-darwin", "darwin64", ".dylib"),
    ("darwin", "arm64"): ("aarch64-darwin", "", ".dylib"),
}


@dataclass(frozen=True)
class FmuOptions:
    """What to package: FMI version, controller form, C real type, where the
    parameters live, the sample time [s] (None: the arm's simulation.sample_time) and the
    observer step (derive generate --observer: explicit or implicit)."""

    fmi: int = 3
    form: str = DEFAULT_FORM
    real: str = "double"
    params: ParamsMode = ParamsMode.BAKED
    sample_time: float | None = None
    observer: str = "explicit"


def check_options(fmi: object, form: object, real: object, params: object,
                  sample_time: object = None, observer: object = "explicit") -> FmuOptions:
    """Validated options; one DeriveError naming every bad one (option, expected, given)."""
    problems = []
    if str(fmi) not in {str(v) for v in FMI_VERSIONS}:
        problems.append(f"--fmi: expected 2 or 3, got {fmi!r}")
    if form not in FORMS:
        problems.append(f"--form: expected one of {', '.join(FORMS)}, got {form!r}")
    if real not in REALS:
        problems.append(f"--real: expected one of {', '.join(REALS)}, got {real!r}")
    modes = [m.value for m in ParamsMode]
    if str(getattr(params, "value", params)) not in modes:
        problems.append(f"--params: expected one of {', '.join(modes)}, got {params!r}")
    if sample_time is not None and not (isinstance(sample_time, (int, float)) and not isinstance(sample_time, bool)
                                        and math.isfinite(sample_time) and sample_time > 0):
        problems.append(f"--sample-time: expected a finite number of seconds > 0, got {sample_time!r}")
    if observer not in OBSERVER_STEPS:
        problems.append(f"--observer: expected one of {', '.join(OBSERVER_STEPS)}, got {observer!r}")
    if problems:
        raise DeriveError("; ".join(problems))
    return FmuOptions(int(str(fmi)), str(form), str(real), ParamsMode(getattr(params, "value", params)),
                      None if sample_time is None else float(sample_time), str(observer))


def platform_names() -> tuple[str, str, str]:
    """(FMI 3 platform tuple, FMI 2 platform folder, library suffix) of this machine."""
    key = (sys.platform.rstrip("0123456789"), platform.machine())
    if key not in PLATFORMS:
        raise DeriveError(f"binary FMU: expected a platform of {', '.join('/'.join(k) for k in PLATFORMS)}, "
                          f"got {'/'.join(key)}")
    return PLATFORMS[key]


def fmi_headers(fmi: int) -> dict[str, str]:
    """The FMI standard's headers of version ``fmi`` (package data, see headers/README.md)."""
    folder = resources.files("derive.fmu") / "headers" / f"fmi{fmi}"
    return {name: folder.joinpath(name).read_text(encoding="utf-8") for name in HEADERS[fmi]}


def token_of(parts: dict[str, str]) -> str:
    """A GUID-formatted instantiation token from a sha256 of ``parts`` (sorted)."""
    h = hashlib.sha256()
    for name, text in sorted(parts.items()):
        h.update(name.encode() + b"\0" + text.encode() + b"\0")
    x = h.hexdigest()
    return f"{{{x[:8]}-{x[8:12]}-{x[12:16]}-{x[16:20]}-{x[20:32]}}}"


def compile_library(cc: str, sources: dict[str, str], name: str) -> bytes:
    """Build the C files of ``sources`` (relative names, all in one folder) into a
    shared library with the host compiler ``cc``; its bytes. The folder is a fresh
    temporary one and the names are relative, so no path enters the binary."""
    exe = shutil.which(cc)
    if exe is None:
        raise DeriveError(f"--cc: expected a C compiler on PATH, got {cc!r} (not found)")
    with tempfile.TemporaryDirectory(prefix="derive-fmu-") as tmp:
        for rel, text in sources.items():
            (Path(tmp) / rel).write_text(text, encoding="utf-8")
        cmd = [exe, *BUILD_FLAGS, "-o", name, *sorted(r for r in sources if r.endswith(".c")), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        if proc.returncode:
            raise DeriveError(f"compiling the FMU's sources with {cc} failed:\n{proc.stderr[-2000:]}")
        return (Path(tmp) / name).read_bytes()


def zip_bytes(files: dict[str, bytes]) -> bytes:
    """A deterministic zip archive: sorted entries, fixed time and modes, deflated."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, date_time=_EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if name.startswith("binaries/") else 0o644) << 16
            info.create_system = 3  # Unix, whatever the host
            archive.writestr(info, files[name], compresslevel=9)
    return buffer.getvalue()


def controller_sources(d: Derivation, o: FmuOptions, tool: str) -> tuple[str, dict[str, str], dict[str, str]]:
    """(model identifier, sources/ {name: text}, top-level XML {name: text}) of a controller FMU."""
    f = FORMS[o.form]
    v = arm_view(d, o.real, o.params, observer=o.observer)
    library = {rel.split("/", 1)[1]: text for rel, text in library_files(d, o.real, o.params, v).items()}
    model = f"{d.arm.name}_{f.name}"
    glue = f"{model}_fmu.c"
    c_files = tuple(sorted([*(n for n in library if n.endswith(".c")), glue]))
    sample = o.sample_time if o.sample_time is not None else d.arm.simulation.sample_time

    glue_sources, top = _render(o.fmi, lambda token: fmu_view(d, v, f, o.fmi, token=token, tool=tool,
                                                              sample_time=sample,
                                                              duration=d.arm.simulation.duration,
                                                              sources=c_files), glue, library)
    return model, {**library, **fmi_headers(o.fmi), **glue_sources}, top


def _package(d: Derivation, model: str, fmi: int, sources: dict[str, str], top: dict[str, str], cc: str,
             arm_bytes: bytes | None, options: dict[str, object]) -> tuple[str, bytes]:
    """Compile ``sources`` for this platform and zip everything into ``<model>.fmu``."""
    fmi3, fmi2, suffix = platform_names()
    folder = fmi3 if fmi == 3 else fmi2
    if not folder:
        raise DeriveError(f"--fmi 2: FMI 2.0 names no binary folder for {platform.machine()}; use --fmi 3")
    binary = compile_library(cc, {k: t for k, t in sources.items() if not k.endswith(".xml")}, model + suffix)
    files: dict[str, bytes] = {name: text.encode() for name, text in top.items()}
    files.update({f"sources/{name}": text.encode() for name, text in sources.items()})
    files[f"binaries/{folder}/{model}{suffix}"] = binary
    if arm_bytes is not None:
        files[f"documentation/{Path(d.arm.source).name}"] = arm_bytes
    files["documentation/MANIFEST.json"] = manifest_text(d, files, arm_bytes, options, "derive fmu").encode()
    return f"{model}.fmu", zip_bytes(files)


def _render(fmi: int, view_of, glue: str, other: dict[str, str]) -> tuple[dict[str, str], dict[str, str]]:
    """Glue, modelDescription (and FMI 3 buildDescription) of ``view_of(token)``, the token
    a hash of the ``other`` sources and of everything rendered with an empty token."""
    def rendered(token: str) -> tuple[dict[str, str], dict[str, str]]:
        x = view_of(token)
        sources = {glue: render(f"fmu/fmi{fmi}.c.jinja", x=x)}
        if fmi == 3:
            sources["buildDescription.xml"] = render("fmu/buildDescription.xml.jinja", x=x)
        return sources, {"modelDescription.xml": render(f"fmu/modelDescription{fmi}.xml.jinja", x=x)}

    draft = rendered("")
    return rendered(token_of({**other, **draft[0], **draft[1]}))


def controller_fmu(d: Derivation, o: FmuOptions, cc: str = "cc", arm_bytes: bytes | None = None) -> tuple[str, bytes]:
    """(file name, bytes) of the co-simulation FMU of ``d``'s controller as ``o`` says."""
    tool = f"derive {metadata.version('derive')}"
    model, sources, top = controller_sources(d, o, tool)
    options = {"fmi": o.fmi, "form": o.form, "real": o.real, "params": o.params.value,
               "sample_time": o.sample_time, **({"observer": o.observer} if o.observer != "explicit" else {})}
    return _package(d, model, o.fmi, sources, top, cc, arm_bytes, options)


def plant_fmu(d: Derivation, fmi: int, cc: str = "cc", arm_bytes: bytes | None = None,
              sample_time: float | None = None) -> tuple[str, bytes]:
    """(file name, bytes) of the co-simulation FMU of the arm's simulation plant
    (derive.fmu.plant), FMI ``fmi``; its default step is the controller's sample time."""
    from derive.fmu.describe import plant_view

    tool = f"derive {metadata.version('derive')}"
    model = f"{d.arm.name}_plant"
    glue = f"{model}_fmu.c"
    sample = sample_time if sample_time is not None else d.arm.simulation.sample_time
    sources, top = _render(fmi, lambda token: plant_view(d, fmi, token=token, tool=tool, sample_time=sample,
                                                          sources=(glue,)), glue, {})
    sources.update(fmi_headers(fmi))
    return _package(d, model, fmi, sources, top, cc, arm_bytes,
                    {"fmi": fmi, "plant": True, "sample_time": sample_time})


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_fmus(out: Path, fmus: dict[str, bytes]) -> list[Path]:
    """Write each FMU into folder ``out`` (created if missing) by an atomic rename:
    a failure leaves no partial file and the previous FMU of that name intact."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise EmitError(f"--out {out}: expected a folder, got a file")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise EmitError(f"--out {out}: cannot create the folder ({exc.strerror or exc})") from None
    written = []
    for name, data in sorted(fmus.items()):
        target = out / name
        if target.is_dir():
            raise EmitError(f"--out {out}: expected {name} to be a file or absent, got a folder")
        tmp = None
        try:
            with tempfile.NamedTemporaryFile(dir=out, prefix=f".{name}.", delete=False) as handle:
                tmp = Path(handle.name)
                handle.write(data)
            tmp.chmod(0o666 & ~_umask())
            tmp.replace(target)
        except OSError as exc:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
            raise EmitError(f"--out {out}: cannot write {name} ({exc.strerror or exc})") from None
        written.append(target)
    return written
