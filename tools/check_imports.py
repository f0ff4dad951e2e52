#!/usr/bin/env python3
"""The source's import graph against docs/architecture.md's one-way flow.

Reads every `crate::…` and `super::…` path in src/**/*.rs (use lines and inline paths; comments,
strings and char literals stripped; a mod.rs's bare paths to its own children are not read),
resolves it to the file that defines that module, and reports:
  - imports against the flow: a file of one top-level module using a module later in
    LAYERS (the shared leaves may be used from anywhere and use only each other and io);
  - circles between files (strongly connected components of the file graph);
  - files over 800 lines and functions over 120 lines.
Exit status 1 when anything is found. Usage: python3 tools/check_imports.py [--quiet]
"""
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
# docs/architecture.md: a module uses only modules to its left.
LAYERS = ["io", "sensor", "data", "capture", "kernels", "models", "train", "eval", "onnx", "runner",
          "experiments", "cli"]
LEAVES = {"error", "config", "rng", "linalg", "stats", "plot", "device", "lib"}
# `models` reads two constants of `data` on purpose (docs/architecture.md); data is to its left.
MAX_FILE, MAX_FN = 800, 120


def strip(text):
    """Source without comments, string and char literals (newlines kept, so line numbers hold)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r"r(#*)\"", text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            end = n if end < 0 else end + 1 + len(hashes)
            out.append("\n" * text.count("\n", i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append("\n" * text.count("\n", i, j + 1))
            i = j + 1
        elif c == "'" and re.match(r"'(?:\\.|\\u\{[0-9a-fA-F]+\}|[^\\'\n])'", text[i:]):
            m = re.match(r"'(?:\\.|\\u\{[0-9a-fA-F]+\}|[^\\'\n])'", text[i:])
            out.append("' '")
            i += len(m.group(0))
        else:
            out.append(c)
            i += 1
    return "".join(out)


def module_of(path):
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod":
        parts = parts[:-1]
    return parts


def files():
    return sorted(p for p in SRC.rglob("*.rs") if p.name != "main.rs")


def resolve(parts, table):
    """The longest module prefix of `parts` that is a file."""
    for n in range(len(parts), 0, -1):
        f = table.get(tuple(parts[:n]))
        if f is not None:
            return f
    return None


def uses(text, own, is_mod):
    """Module paths (lists of segments, from the crate root) a file refers to through
    `crate::`, `super::` or `self::`."""
    out = []
    # `self` is the file's own module; `super` its parent (a mod.rs is its folder's module).
    base = own if is_mod else own[:-1]
    for m in re.finditer(r"\buse\s+((?:super::)+|self::)([^;]+);", text):
        up = m.group(1).count("super")
        root = base[: len(base) - up] if up else own
        out.extend(root + e for e in expand(m.group(2).replace("\n", " ")))
    for m in re.finditer(r"(?<![:\w])((?:super::)+)((?:[A-Za-z_][A-Za-z0-9_]*::)*[A-Za-z_][A-Za-z0-9_]*)", text):
        up = m.group(1).count("super")
        out.append(base[: len(base) - up] + m.group(2).split("::"))
    # use crate::a::{b, c::{d, e}};  -> expand one level of braces per group
    for m in re.finditer(r"\buse\s+crate::([^;]+);", text):
        out.extend(expand(m.group(1).replace("\n", " ")))
    for m in re.finditer(r"\bcrate::((?:[A-Za-z_][A-Za-z0-9_]*::)*[A-Za-z_][A-Za-z0-9_]*)", text):
        out.append(m.group(1).split("::"))
    return out


def expand(tree):
    tree = tree.strip()
    if "{" not in tree:
        return [[s.strip() for s in tree.split(" as ")[0].split("::") if s.strip()]]
    head, rest = tree.split("{", 1)
    body = rest.rsplit("}", 1)[0]
    items, depth, cur = [], 0, ""
    for ch in body:
        if ch == "," and depth == 0:
            items.append(cur)
            cur = ""
            continue
        depth += ch == "{"
        depth -= ch == "}"
        cur += ch
    items.append(cur)
    prefix = [s for s in head.split("::") if s.strip()]
    out = []
    for it in items:
        if it.strip() in ("", "self"):
            out.append(prefix)
            continue
        for sub in expand(it):
            out.append(prefix + sub)
    return out


def sccs(graph):
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    return out


def long_functions(path, text):
    """(name, lines) of fns over MAX_FN lines, by brace matching on the stripped source."""
    lines = text.split("\n")
    found = []
    for i, line in enumerate(lines):
        m = re.match(r"\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?fn\s+(\w+)", line)
        if not m:
            continue
        depth, started = 0, False
        for j in range(i, len(lines)):
            depth += lines[j].count("{") - lines[j].count("}")
            if "{" in lines[j]:
                started = True
            if started and depth <= 0:
                n = j - i + 1
                if n > MAX_FN:
                    found.append((m.group(1), i + 1, n))
                break
            if not started and ";" in lines[j]:
                break
    return found


def main():
    quiet = "--quiet" in sys.argv
    table = {tuple(module_of(p)): p for p in files()}
    graph, against, long_files, long_fns = {}, [], [], []
    for p in files():
        raw = p.read_text()
        text = strip(raw)
        own = module_of(p)
        top = own[0] if own else "lib"
        deps = set()
        for parts in uses(text, own, p.name == "mod.rs"):
            target = resolve(parts, table)
            if target is None or target == p:
                continue
            deps.add(target)
            ttop = module_of(target)[0] if module_of(target) else "lib"
            if top in LAYERS and ttop in LAYERS and LAYERS.index(ttop) > LAYERS.index(top):
                against.append((p, target))
            if top in LEAVES and ttop in LAYERS and ttop != "io":
                against.append((p, target))
        graph[p] = deps
        n = raw.count("\n")
        if n > MAX_FILE:
            long_files.append((p, n))
        long_fns.extend((p, *f) for f in long_functions(p, text))
    circles = sccs(graph)
    rel = lambda p: p.relative_to(ROOT)
    for a, b in sorted(set(against)):
        print(f"against the flow: {rel(a)} uses {rel(b)}")
    for c in circles:
        print("circle: " + " ↔ ".join(str(rel(p)) for p in c))
    for p, n in long_files:
        print(f"file over {MAX_FILE} lines: {rel(p)} ({n})")
    for p, name, line, n in long_fns:
        print(f"function over {MAX_FN} lines: {rel(p)}:{line} {name} ({n})")
    bad = len(set(against)) + len(circles) + len(long_files) + len(long_fns)
    if not quiet:
        print(f"{len(graph)} files: {len(set(against))} imports against the flow, "
              f"{len(circles)} circles, {len(long_files)} long files, {len(long_fns)} long functions")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
