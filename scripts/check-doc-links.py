#!/usr/bin/env python3
"""Check that the docs' relative links resolve.

Every relative Markdown link in README.md, CHANGELOG.md and docs/** must name a file that
exists and, when it has an anchor, a heading of that file under GitHub's anchor rules
(lower case; letters, digits, spaces, hyphens and underscores kept; spaces to hyphens; a
repeated heading gets -1, -2, ...). Paths to docs/*.md named in Rust sources (doc comments
and --help texts print them) must exist too, and a section they quote, as in
`docs/accuracy.md, "Windows sized to the sensor"`, must begin a heading of that file.

    python3 scripts/check-doc-links.py    # from the repository's root; exit status 1 on a miss
"""

import os
import pathlib
import re
import sys
import unicodedata
import urllib.parse

ROOT = pathlib.Path(__file__).resolve().parent.parent
LINK = re.compile(r"\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def lines_outside_fences(text):
    fence = None
    for number, line in enumerate(text.split("\n"), 1):
        marker = re.match(r"^\s{0,3}(```|~~~)", line)
        if marker:
            fence = None if fence == marker.group(1) else (fence or marker.group(1))
            continue
        if fence is None:
            yield number, line


def slug(heading):
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip()).replace("`", "").lower()
    kept = "".join(c for c in text if c in " -_" or unicodedata.category(c)[0] in "LMN")
    return kept.replace(" ", "-")


def headings(path):
    """The file's headings in order, and the anchors GitHub makes of them."""
    names, anchors, seen = [], set(), {}
    for _, line in lines_outside_fences(path.read_text(encoding="utf-8")):
        m = re.match(r"^\s{0,3}#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m:
            names.append(m.group(1))
            base = slug(m.group(1))
            n = seen.get(base, 0)
            seen[base] = n + 1
            anchors.add(base if n == 0 else f"{base}-{n}")
    return names, anchors


def main():
    cache = {}

    def of(path):
        if path not in cache:
            cache[path] = headings(path)
        return cache[path]

    docs = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]
    bad, links = [], 0
    for doc in docs:
        # Link texts may wrap: the lines outside code blocks read as one text (fenced lines blank).
        kept = dict(lines_outside_fences(doc.read_text(encoding="utf-8")))
        text = "\n".join(kept.get(n, "") for n in range(1, max(kept, default=0) + 1))
        for m in LINK.finditer(text):
            number = text.count("\n", 0, m.start(1)) + 1
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):
                continue  # http:, https:, mailto:
            links += 1
            path, _, anchor = target.partition("#")
            file = (doc.parent / urllib.parse.unquote(path)).resolve() if path else doc
            where = f"{doc.relative_to(ROOT)}:{number}: {target}"
            if not file.exists():
                bad.append(f"{where}: no such file")
            elif anchor and file.suffix == ".md" and urllib.parse.unquote(anchor) not in of(file)[1]:
                bad.append(f"{where}: no such heading in {file.relative_to(ROOT)}")

    mentions = 0
    sources = []
    for folder, subfolders, files in os.walk(ROOT):
        subfolders[:] = [d for d in subfolders if d not in ("target", ".git")]
        sources += [pathlib.Path(folder) / f for f in files if f.endswith(".rs")]
    for source in sorted(sources):
        text = source.read_text(encoding="utf-8")
        # Doc comments and strings wrap: read them as one line, their markers taken out.
        flat = re.sub(r"\s*\n\s*(?:///?!?|//)?\s*", " ", text)
        for m in re.finditer(r"(docs/[\w/.-]+\.md)((?:[,:]?\s*\"[^\"]+\")*)", flat):
            mentions += 1
            file = ROOT / m.group(1)
            if not file.exists():
                bad.append(f"{source.relative_to(ROOT)}: {m.group(1)}: no such file")
                continue
            for section in re.findall(r"\"([^\"]+)\"", m.group(2)):
                if not any(name.startswith(section) for name in of(file)[0]):
                    bad.append(f"{source.relative_to(ROOT)}: {m.group(1)}, \"{section}\": no such heading")

    for line in bad:
        print(line)
    print(f"{links} relative links in {len(docs)} Markdown files, {mentions} docs/ paths in Rust sources: "
          + (f"{len(bad)} broken" if bad else "all resolve"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
