"""The house rules of derive/ (issue 36): no import circle anywhere (every import statement, at any depth,
TYPE_CHECKING included), no module over 400 lines, and derive/control split by concept into packages of
fewer than 15 modules each (the laws at its top, sampling/, certificate/, payload/)."""
from __future__ import annotations

import ast
from pathlib import Path

DERIVE = Path(__file__).resolve().parent.parent / "derive"
MAX_LINES = 400
MAX_MODULES = 15


def _modules() -> dict[str, Path]:
    out = {}
    for p in DERIVE.rglob("*.py"):
        rel = p.relative_to(DERIVE.parent).with_suffix("")
        out[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = p
    return out


def _graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    def resolve(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    edges: dict[str, set[str]] = {m: set() for m in mods}
    for m, p in mods.items():
        pkg = m if p.name == "__init__.py" else m.rpartition(".")[0]
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = pkg.split(".")
                    base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
                targets = [f"{base}.{a.name}" for a in node.names] + [base]
            else:
                continue
            for t in targets:
                r = resolve(t) if t.startswith("derive") else None
                if r is not None and r != m:
                    edges[m].add(r)
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_import_circle_in_derive():
    """No two modules of derive/ import each other, directly or through others (any import statement)."""
    assert _cycles(_graph(_modules())) == []


def test_the_cycle_check_finds_a_circle():
    """The check itself can fail: a two-module circle is found."""
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": set()}) == [["a", "b"]]


def test_no_module_over_400_lines():
    """Every module of derive/ is at most 400 lines."""
    long = {str(p.relative_to(DERIVE.parent)): n for p in DERIVE.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}


def test_control_packages_by_concept():
    """derive/control: the laws at its top, and packages sampling/, certificate/ and payload/, each under 15 modules."""
    control = DERIVE / "control"
    packages = {p.name for p in control.iterdir() if (p / "__init__.py").exists()}
    assert {"sampling", "certificate", "payload"} <= packages
    for folder in [control] + [control / name for name in packages]:
        assert len(list(folder.glob("*.py"))) < MAX_MODULES, folder
