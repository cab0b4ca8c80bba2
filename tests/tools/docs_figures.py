#!/usr/bin/python3
"""The figures of docs/*.md come from the commands printed next to them, and reproduce.

A figure block in a page: a ```sh block of commands (lines starting with build/, backslash continuations) followed
directly by a plain ``` block holding what they print: torque-eval table rows ("est = truth  cycle|tooth  N ...")
and misfire lines. Each such pair is run in page order (/tmp/ paths moved to one temporary directory per page, so
a block may use what an earlier one recorded; in the source tree) and the
printed rows compared, in order, field by field: a figure matches when the measured value rounds to it (to the
page's last digit; tests/tools/readme_figures.py has the rule). The README has its own checker (readme_figures.py).
Usage: docs_figures.py BUILD_DIR SOURCE_DIR [--update]. Exit 0 all match; 1 a figure differs or a command failed;
2 usage. --update rewrites each printed row of the pages with the line the command prints now (commit it saying
why the figures moved).
"""
import glob
import os
import re
import shlex
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import readme_figures as rf  # noqa: E402  (rounds_to, check, run, the failure list)

ROW = re.compile(r"^(\S+ = \S+)\s+(cycle|tooth)\s+(.*)$")
MISFIRE = re.compile(r"^misfire: (\d+) true, (\d+) detected \(recall (\S+) %\), (\d+) false alarms in (\d+)")


def figures(text):
    """(name, [(label, [fields])]) of every printed row and misfire line of a block, in order."""
    out = []
    for line in text.splitlines():
        m = ROW.match(line)
        if m:
            out.append((m.group(1), m.group(3).split()))
        m = MISFIRE.match(line)
        if m:
            out.append(("misfire", list(m.groups())))
    return out


def blocks(page):
    """(commands, expected figures) of each ```sh block followed directly by a plain ``` block with figures."""
    pairs = re.findall(r"```sh\n((?:(?!```).)*)```\n```\n((?:(?!```).)*)```", page, re.S)
    for cmds, printed in pairs:
        want = figures(printed)
        if want:
            lines = cmds.replace("\\\n", " ").splitlines()
            yield [c.split("#")[0].strip() for c in lines if c.strip().startswith("build/")], want


def run_block(name, cmds, want, build, src, tmp):
    got = []
    for c in cmds:
        argv = [a.replace("/tmp/", tmp + "/") for a in shlex.split(c)]
        argv[0] = os.path.join(build, os.path.relpath(argv[0], "build"))
        got += figures(rf.run(argv, src))
    if [w[0] for w in want] != [g[0] for g in got]:
        rf.failures.append(f"{name}: the page shows rows {[w[0] for w in want]}, the commands print {[g[0] for g in got]}")
        return
    for k, ((label, wf), (_, gf)) in enumerate(zip(want, got)):
        for i, (w, g) in enumerate(zip(wf, gf)):
            if w == "-" or g == "-" or not re.fullmatch(rf.NUM, w):
                if w != g:
                    rf.failures.append(f"{name} row {k + 1} ({label}) field {i + 1}: page '{w}', command '{g}'")
                continue
            rf.check(f"{name} row {k + 1} ({label}) field {i + 1}", w, float(g))


def printed_lines(text):
    """The lines of `text` that figures() reads, in order."""
    return [ln for ln in text.splitlines() if ROW.match(ln) or MISFIRE.match(ln)]


def update_page(path, build, src):
    """Rewrites the printed rows of every figure block of one page with what its commands print now."""
    with open(path, encoding="utf-8") as f:
        page = f.read()
    pat = re.compile(r"(```sh\n((?:(?!```).)*)```\n```\n)((?:(?!```).)*)(```)", re.S)
    with tempfile.TemporaryDirectory(prefix="docs_figures_") as tmp:
        def repl(m):
            cmds, printed = m.group(2), m.group(3)
            if not figures(printed):
                return m.group(0)
            lines = cmds.replace("\\\n", " ").splitlines()
            out = []
            for c in [c.split("#")[0].strip() for c in lines if c.strip().startswith("build/")]:
                argv = [a.replace("/tmp/", tmp + "/") for a in shlex.split(c)]
                argv[0] = os.path.join(build, os.path.relpath(argv[0], "build"))
                out += printed_lines(rf.run(argv, src))
            it = iter(out)
            new = [next(it, ln) if (ROW.match(ln) or MISFIRE.match(ln)) else ln for ln in printed.split("\n")]
            return m.group(1) + "\n".join(new) + m.group(4)
        page = pat.sub(repl, page)
    with open(path, "w", encoding="utf-8") as f:
        f.write(page)


def main():
    if len(sys.argv) == 4 and sys.argv[3] == "--update":
        build, src = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
        for path in sorted(glob.glob(os.path.join(src, "docs", "*.md"))):
            update_page(path, build, src)
        return 0
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    build, src = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    n_blocks = 0
    for path in sorted(glob.glob(os.path.join(src, "docs", "*.md"))):
        with open(path, encoding="utf-8") as f:
            page = f.read()
        with tempfile.TemporaryDirectory(prefix="docs_figures_") as tmp:  # one per page: blocks build on each other
            for j, (cmds, want) in enumerate(blocks(page)):
                run_block(f"{os.path.relpath(path, src)} block {j + 1}", cmds, want, build, src, tmp)
                n_blocks += 1
    for f in rf.failures:
        print("MISMATCH " + f)
    print(f"docs figures: {n_blocks} blocks, {rf.checked} figures checked, {len(rf.failures)} differ")
    return 1 if rf.failures or n_blocks == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
