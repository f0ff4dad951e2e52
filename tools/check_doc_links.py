#!/usr/bin/env python3
"""Check that the documentation's references resolve.

Checks every Markdown file in docs/ and the top-level *.md files:
- relative Markdown links [text](path) and [text](path#anchor): the file exists, and the
  anchor is a heading of that file (GitHub's anchor rule);
- plain-text references to docs/NAME.md, src/..., tests/..., tools/..., configs/... and
  benches/... paths: the path exists (globs and templated names are skipped).

docs/gpu.md may be named before it exists (pass --allow PATH for others).
Exit status 1 when anything is broken; every broken reference is printed as FILE:LINE.
"""
import argparse
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
PLAIN = re.compile(r"(?<![\w./-])((?:docs|src|tests|tools|configs|benches)/[\w./-]*\w)")


def anchor(heading):
    h = heading.strip().lower()
    h = re.sub(r"[^\w\- ]", "", h)
    return h.replace(" ", "-")


def anchors(path):
    out = set()
    in_code = False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        if not in_code and line.startswith("#"):
            out.add(anchor(line.lstrip("#")))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--allow", action="append", default=["docs/gpu.md"])
    args = ap.parse_args()
    allowed = {ROOT / a for a in args.allow}
    files = sorted((ROOT / "docs").glob("*.md")) + sorted(ROOT.glob("*.md"))
    bad = 0
    for f in files:
        for n, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            for target in LINK.findall(line):
                if re.match(r"[a-z]+:", target):
                    continue
                path, _, frag = target.partition("#")
                p = (f.parent / path).resolve() if path else f
                if p in allowed:
                    continue
                if not p.exists():
                    print(f"{f.relative_to(ROOT)}:{n}: missing {target}")
                    bad += 1
                elif frag and p.suffix == ".md" and frag not in anchors(p):
                    print(f"{f.relative_to(ROOT)}:{n}: no heading for #{frag} in {path or f.name}")
                    bad += 1
            for m in PLAIN.finditer(line):
                ref = m.group(1)
                following = line[m.end():m.end() + 1]
                if following in "*{<" and following or ref.endswith("/"):
                    continue
                p = ROOT / ref
                if p in allowed or p.exists():
                    continue
                print(f"{f.relative_to(ROOT)}:{n}: missing {ref}")
                bad += 1
    print(f"{len(files)} files checked, {bad} broken reference(s)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
