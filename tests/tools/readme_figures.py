#!/usr/bin/python3
"""The README's figures come from the commands it names, and reproduce.

Runs the README's deterministic commands (fast replay, torque-eval, torque-accuracy --recording, torque-na-repro,
the quick commands of "Running it") and compares every figure the README prints for them with what the commands
print now. A README figure "matches" when the measured value rounds to it (to the README's last digit).
Usage: readme_figures.py BUILD_DIR SOURCE_DIR. Exit 0 all match; 1 a figure differs (each one listed) or a
command failed; 2 usage. The slow beds (torque-accuracy --bed, --cylinders) are not run here: their ctest subsets
(DaemonBed, the cylinder tests) assert the targets.
"""
import os
import re
import subprocess
import sys
import tempfile

NUM = r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
failures = []
checked = 0


def rounds_to(readme: str, value: float) -> bool:
    """True if value rounds to the README's figure at the README's precision ("1.05e3": ±5, "0.524": ±0.0005)."""
    m = re.fullmatch(r"([-+]?\d+)(?:\.(\d+))?(?:e([-+]?\d+))?", readme)
    if not m:
        return False
    decimals = len(m.group(2) or "")
    exp = int(m.group(3) or 0)
    half_ulp = 0.5 * 10.0 ** (exp - decimals)
    return abs(value - float(readme)) <= half_ulp * (1 + 1e-9) + 1e-12


def check(name: str, readme: str, value: float) -> None:
    global checked
    checked += 1
    if not rounds_to(readme, value):
        failures.append(f"{name}: README says {readme}, the command gives {value:.6g}")


def run(cmd, cwd, **kw) -> str:
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300, **kw)
    if r.returncode != 0:
        failures.append(f"command failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return r.stdout


def eval_rows(text: str) -> dict:
    """torque-eval table rows: 'est = truth' -> [N, bias, RMS, max, SD, ISE, cyc%err]."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"^(\S+ = \S+)\s+(cycle|tooth)\s+(.*)$", line)
        if m:
            rows[m.group(1)] = m.group(3).split()
    return rows


def prose(pattern: str) -> str:
    """A README sentence as a regex: any run of spaces may be a line break."""
    return pattern.replace(" ", r"\s+")


def section(readme: str, start: str) -> str:
    i = readme.find(start)
    if i < 0:
        failures.append(f"README: section starting '{start}' not found")
        return ""
    return readme[i:]


def check_demo(readme, build, src, tmp):
    """The demo table (fast replay gives the paced run's values) and the second run from learned state."""
    text = section(readme, "On this machine the demo gives:")
    block = text.split("```")[1] if text else ""
    want = eval_rows(block)
    rec = os.path.join(tmp, "demo")
    run([f"{build}/service/torqued", "--config", "config/demo.yaml", "--replay", "fast", "--no-dds", "--fresh-state",
         "--record", rec], src)
    cols = [c for pair in want for c in ("--column", pair.replace(" = ", "="))]
    got = eval_rows(run([f"{build}/tools/torque-eval", "--estimate", f"{rec}/engine_cycle.csv", "--truth",
                         "data/demo/truth_cycle.csv", *cols, "--where", "quality=0"], src))
    if not want:
        failures.append("README: no torque-eval rows in the demo block")
    for pair, fields in want.items():
        for k, (w, g) in enumerate(zip(fields, got.get(pair, []))):
            check(f"demo {pair} field {k + 1}", w, float(g))
        if pair not in got:
            failures.append(f"demo: torque-eval printed no row {pair}")
    m = re.search(prose(r"second run of the same recording gives indicated (" + NUM + r") N·m RMS"), text)
    if not m:
        failures.append("README: the demo's second-run figure was not found")
        return
    state = os.path.join(tmp, "second-run-state")
    for i in (1, 2):
        run([f"{build}/service/torqued", "--config", "config/demo.yaml", "--replay", "fast", "--no-dds",
             "--state-dir", state, "--record", f"{rec}{i}"], src)
    got = eval_rows(run([f"{build}/tools/torque-eval", "--estimate", f"{rec}2/engine_cycle.csv", "--truth",
                         "data/demo/truth_cycle.csv", "--column", "indicated_nm=t_ind_mean_nm", "--where",
                         "quality=0"], src))
    check("demo second run indicated RMS", m.group(1), float(got["indicated_nm = t_ind_mean_nm"][2]))


def check_vehicle(readme, build, src, tmp):
    """The demo as a vehicle sees it: the README's two torque-accuracy --recording commands, run as written."""
    text = section(readme, "The demo recording as a vehicle sees it")
    if not text:
        return
    cmds = [ln for ln in text.split("```sh")[1].split("```")[0].splitlines() if ln.strip()]
    out = ""
    for c in cmds:
        argv = [a.replace("/tmp/", tmp + "/") for a in c.split()]
        argv[0] = os.path.join(build, os.path.relpath(argv[0], "build"))
        out = run(argv, src)
    parts = out.split("estimate rows:")  # the fused/brake/indicated/friction table, then the crank-only one
    got = eval_rows(parts[1] if len(parts) > 1 else out)
    after = text.split("```sh")[1].split("```", 1)[1]
    m = re.search(prose(r"fused = brake (" + NUM + r") N·m RMS \(bias (" + NUM + r"), max (" + NUM + r") N·m"), after)
    n = re.search(prose(r"indicated (" + NUM + r") N·m RMS, friction (" + NUM + r") N·m RMS"), after)
    if not m or not n or "fused_nm = t_brake_mean_nm" not in got:
        failures.append(f"vehicle: README figures ({bool(m)}, {bool(n)}) or the command's table ({list(got)}) not found")
        return
    f = got["fused_nm = t_brake_mean_nm"]
    check("vehicle fused RMS", m.group(1), float(f[2]))
    check("vehicle fused bias", m.group(2), float(f[1]))
    check("vehicle fused max", m.group(3), float(f[3]))
    check("vehicle indicated RMS", n.group(1), float(got["indicated_nm = t_ind_mean_nm"][2]))
    check("vehicle friction RMS", n.group(2), float(got["friction_nm = t_fric_mean_nm"][2]))


def check_na(readme, build, src):
    """Na et al. Tables III and IV."""
    out = run([f"{build}/tools/torque-na-repro"], src)
    t3 = out.split("TABLE III")[1].split("TABLE IV")[0] if "TABLE IV" in out else ""
    t4 = out.split("TABLE IV")[1] if "TABLE IV" in out else ""
    tool = {}
    for table, key in ((t3, "III"), (t4, "IV")):
        for line in table.splitlines():
            parts = line.split()
            if parts and parts[0] in ("ISE", "MAE", "SD"):
                tool[(key, parts[0])] = [float(x) for x in parts[1:]]
    for label, idx in (("ISE (N²m²s)", "ISE"), ("MAE (N·m)", "MAE"), ("SD (N·m)", "SD")):
        m = re.search(r"^\| " + re.escape(label) + r" \| (.*) \|$", readme, re.M)
        if not m or ("III", idx) not in tool:
            failures.append(f"Na Table III row {label} not found")
            continue
        for k, w in enumerate(x.strip() for x in m.group(1).split("|")):
            check(f"Na Table III {idx} col {k + 1}", w, tool[("III", idx)][k])
    for label, cols in (("constant gain (50)", (0, 1)), ("time-varying gain (54)", (2, 3))):
        m = re.search(r"^\| " + re.escape(label) + r" \| (.*) \|$", readme, re.M)
        if not m or ("IV", "ISE") not in tool:
            failures.append(f"Na Table IV row {label} not found")
            continue
        for k, cell in zip(cols, m.group(1).split("|")):
            ise, sd = (x.strip() for x in cell.split("/"))
            check(f"Na Table IV {label} ISE", ise, tool[("IV", "ISE")][k])
            check(f"Na Table IV {label} SD", sd, tool[("IV", "SD")][k])


def check_quick_commands(readme, build, src, tmp):
    """'Running it': the commands that end by themselves exit 0."""
    block = section(readme, "## Running it").split("```sh")[1].split("```")[0]
    for line in block.splitlines():
        cmd = line.split("#")[0].strip()
        if not cmd.startswith("build/") or "--replay fast" not in cmd and not any(
                t in cmd for t in ("--check-config", "torque-sim --list", "torque-decode", "torque-eval")):
            continue
        for part in cmd.split(" ; "):
            argv = [a.replace("/tmp/", tmp + "/").replace("out/", tmp + "/out/").replace("out.png", tmp + "/out.png")
                    for a in part.split()]
            argv = [a if a not in ("t.csv", "c.csv") else os.path.join(tmp, a) for a in argv]
            argv[0] = os.path.join(build, os.path.relpath(argv[0], "build"))
            run(argv, src)
            global checked
            checked += 1


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    build, src = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    with open(os.path.join(src, "README.md"), encoding="utf-8") as f:
        readme = f.read()
    with tempfile.TemporaryDirectory(prefix="readme_figures_") as tmp:
        check_quick_commands(readme, build, src, tmp)
        check_demo(readme, build, src, tmp)
        check_vehicle(readme, build, src, tmp)
        check_na(readme, build, src)
    for f in failures:
        print("MISMATCH " + f)
    print(f"README figures: {checked} checked, {len(failures)} differ")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
