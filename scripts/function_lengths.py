#!/usr/bin/env python3
"""Reports the longest Rust functions outside tests, in lines (signature to closing brace).

    scripts/function_lengths.py [--top N] [--limit L] [--fail]

Scans rust/*/src/**/*.rs, leaving out `#[cfg(test)]` modules and `#[test]` functions (the
standards' limit is for code outside tests). Prints the N longest (default 5) and how many are
over L lines (default 80); with --fail, exits 1 when any is. Functions are found by their
`fn` keyword and matched braces, with strings, characters and comments skipped.
"""

import argparse
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
FN = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")


def code_mask(text: str) -> str:
    """The text with comments, strings and character literals blanked (newlines kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:i + 8]) and not text[i - 1:i].isalnum():
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = '"' + hashes
            j = text.find(end, i + len(hashes) + 2)
            j = n if j < 0 else j + len(end)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", text[i:j + 1]))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4] + " "):
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", text[i:])
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching_brace(code: str, open_at: int) -> int:
    depth = 0
    for k in range(open_at, len(code)):
        if code[k] == "{":
            depth += 1
        elif code[k] == "}":
            depth -= 1
            if depth == 0:
                return k
    return len(code) - 1


def test_spans(code: str):
    """Character spans of `#[cfg(test)]` items and `#[test]` functions."""
    spans = []
    for m in re.finditer(r"#\[(cfg\(test\)|test)\]", code):
        brace = code.find("{", m.end())
        semi = code.find(";", m.end())
        if brace < 0 or (0 <= semi < brace):
            continue
        spans.append((m.start(), matching_brace(code, brace)))
    return spans


def functions(path: pathlib.Path):
    code = code_mask(path.read_text(encoding="utf-8"))
    skip = test_spans(code)
    for m in FN.finditer(code):
        if any(a <= m.start() <= b for a, b in skip):
            continue
        # The body's brace: the first `{` after the signature, unless a `;` (a declaration
        # without body, as in traits and extern blocks) comes first.
        brace = code.find("{", m.end())
        semi = code.find(";", m.end())
        if brace < 0 or (0 <= semi < brace):
            continue
        end = matching_brace(code, brace)
        first = code.count("\n", 0, m.start()) + 1
        last = code.count("\n", 0, end) + 1
        yield (last - first + 1, f"{path.relative_to(ROOT)}:{first}", m.group(1))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=5)
    ap.add_argument("--limit", type=int, default=80)
    ap.add_argument("--fail", action="store_true")
    a = ap.parse_args()
    found = []
    for path in sorted(ROOT.glob("rust/*/src/**/*.rs")):
        found.extend(functions(path))
    found.sort(reverse=True)
    over = [f for f in found if f[0] > a.limit]
    print(f"{len(found)} functions outside tests; {len(over)} over {a.limit} lines")
    for lines, where, name in found[: max(a.top, 0)]:
        print(f"{lines:5d} lines  {name}  {where}")
    return 1 if a.fail and over else 0


if __name__ == "__main__":
    sys.exit(main())
