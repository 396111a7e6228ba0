"""``make demo``: the whole tool on every shipped machine, written to one folder.

For each shipped machine (``assets/machines/``): its CAD export -> converter -> MJCF -> tool motion
-> simulation (against the machine's own speed measurements where it ships them) ->
probes, clearance, a faulty design variant and the 3-D animation -> diagnosis of a virtual
bench recording with a concealed effect; then ``index.html`` links every plot and file. The
demo uses only the public API (``import mechanism``); the folder is assembled aside and
swapped into place at the end, so a failed run never leaves half a demo behind.
"""

from __future__ import annotations

import html
import json
import os
import time
from pathlib import Path

import numpy as np

import mechanism

DEMO_EFFECT = "torque_ripple"  # the concealed effect of the demo's bench recording
DEMO_SEED = 3
# half the benchmark's minute: a ripple shows in every second of it, and the three machines'
# diagnoses took 19 of the demo's 32 s on one core at 60 s
DEMO_RECORDING_S = 30.0
# fractions of the top voltage
STEPS_V = (
    np.array([0.0, 1.5, 3.0, 4.5, 5.5]),
    np.array([0.2, 0.5, 0.8, 0.0, 0.3]),
)
TOP_VOLTAGE_V = 24.0
# a servo's goal steps instead, at the same times: fractions of the shaft's travel
GOAL_FRACTIONS = np.array([0.5, 0.8, 0.2, 0.5, 0.65])
# added inertia up to 4x the shaft side's own
FLYWHEEL_MULTIPLE, FLYWHEEL_STEPS, FLYWHEEL_RUN_S = (
    4.0,
    9,
    3.0,
)


class _Steps:
    def __init__(self, total: int):
        self.total, self.done, self.started = total, 0, time.perf_counter()

    def __call__(self, what: str) -> None:
        self.done += 1
        print(f"[{self.done}/{self.total}] {what}", flush=True)


def _convert(machine: mechanism.Machine, out: Path, final: Path) -> dict:
    export = mechanism.shipped_export(machine.name)
    if export is None:
        return {
            "lines": [
                f"{machine.name}: no CAD export shipped; the model is {machine.model_path.name}"
            ]
        }
    # the export's up axis: the description's, else the export's own gravity vector, else z
    report = mechanism.convert(
        export, out / "model", up=machine.description.section("machine").get("up")
    )
    lines = [line.replace(str(out), str(final)) for line in mechanism.conversion_summary(report)]
    (out / "model" / "conversion.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    counts = {
        "parts": report.n_parts,
        "bodies": report.n_bodies,
        "joints": report.n_joints,
        "loop_closures": report.n_loop_closures,
        "couplings": report.n_couplings,
        "degrees_of_freedom": report.degrees_of_freedom,
    }
    return {"lines": lines, "mjcf": f"model/{report.mjcf_path.name}", "counts": counts}


def _tool(machine: mechanism.Machine, out: Path) -> dict | None:
    if not machine.tool_site:
        return None
    motion = mechanism.tool_motion(machine)
    mechanism.write_tool_motion_csv(motion, out / "tool.csv")  # the historical columns, as before
    mechanism.plot_tool_motion(motion, out / "tool.png")
    return {
        "stroke_mm": motion.stroke_mm,
        "hook_passage_deg": motion.hook_passage_angle_deg,
        "needle_rise_at_passage_mm": motion.tool_rise_at_passage_mm,  # the demo.json key kept
        "hook_point_clearance_mm": motion.hook_point_clearance_mm,
        "summary": motion.summary_lines(),
    }


def _steady_speeds_path(machine: mechanism.Machine) -> Path:
    return mechanism.shipped_folder("measurements", machine.name) / "steady_speeds.csv"


def steady_speeds(machine: mechanism.Machine) -> list[dict]:
    """The machine's shipped steady-speed measurements (``assets/measurements/<name>/steady_speeds.csv``:
    motor voltage, warm-up time, shaft speed; no tool load) against the full model."""
    path = _steady_speeds_path(machine)
    if not path.is_file():
        return []
    table = mechanism.read_table(path, required=["motor_voltage_V", "warm_s", "speed_rpm"])
    rows, machines = [], {}
    for volts, warm_s, measured in zip(
        table["motor_voltage_V"], table["warm_s"], table["speed_rpm"]
    ):
        if warm_s not in machines:
            machines[warm_s] = mechanism.load_machine(
                machine.description, needle=False, warm_s=float(warm_s)
            )
        model = mechanism.simulate(
            machines[warm_s], voltage_V=float(volts), duration_s=3.0
        ).mean_speed_rpm
        rows.append(
            {
                "motor_voltage_V": float(volts),
                "warm_s": float(warm_s),
                "measured_rpm": float(measured),
                "model_rpm": model,
                "error_percent": (model / measured - 1) * 100,
            }
        )
    return rows


def _simulate(machine: mechanism.Machine, out: Path) -> dict:
    facts: dict = {"steady_speeds": steady_speeds(machine)}
    if facts["steady_speeds"]:
        rows = facts["steady_speeds"]
        mechanism.write_table(
            out / "steady_speeds.csv",
            {key: [row[key] for row in rows] for key in rows[0]},
            comments=[
                "measured steady shaft speeds (no tool load) against the full multibody model"
            ],
        )
    inputs, comment = _steps(machine)
    run = mechanism.simulate(machine, voltage_V=inputs, duration_s=7.0)
    mechanism.write_table(out / "simulate_steps.csv", run.columns(), comments=[comment])
    mechanism.plot_simulation(run, out / "simulate_steps.png")
    facts["steps_final_rpm"] = run.mean_speed_rpm
    if machine.fabric_capable:
        sewing = mechanism.simulate(
            mechanism.load_machine(machine.description, layers=12), voltage_V=7.0, duration_s=3.0
        )
        mechanism.write_table(
            out / "sewing_12_layers.csv", sewing.columns(), comments=["7 V, through 12 layers"]
        )
        mechanism.plot_simulation(sewing, out / "sewing_12_layers.png")
        facts["sewing_mean_rpm"] = sewing.mean_speed_rpm
    return facts


def _steps(machine: mechanism.Machine) -> tuple:
    """The main motor's input steps and what they are: voltage steps for a dc motor, goal steps
    over the shaft's travel (in the servo joint's own coordinate) for a servo."""
    times, fractions = STEPS_V
    kind = machine.description.drive_tables[machine.motor_joint]["type"]
    if kind == "dc":
        steps = mechanism.VoltageProfile(times, fractions * TOP_VOLTAGE_V)
        return steps, "voltage steps " + " / ".join(f"{v:g}" for v in steps.voltage_V) + " V"
    if kind != "servo":
        raise mechanism.UserError(
            f"the demo steps a dc motor's voltage or a servo's goal; the main motor on "
            f"{machine.motor_joint} is a {kind} drive"
        )
    low, high = machine.shaft_span_rad or (0.0, 2 * np.pi)
    shaft = low + GOAL_FRACTIONS * (high - low)
    goals = []
    for angle in shaft:  # the servo joint's position with the shaft there
        machine.reset(float(angle))
        goals.append(float(machine.data.qpos[machine.motor_qpos]))
    machine.reset(0.0)
    text = " / ".join(f"{np.degrees(a):.4g}" for a in shaft)
    return {machine.motor_joint: mechanism.VoltageProfile(times, np.array(goals))}, (
        f"servo goal steps on {machine.motor_joint}: shaft at {text} deg"
    )


def _flywheel(machine: mechanism.Machine, out: Path) -> dict | None:
    """The thesis's open question: what a bigger flywheel on the shaft buys (less speed ripple)
    and costs (a slower start), at the machine's described voltages."""
    voltages = machine.description.section("inspect").get("flywheel_voltages_V")
    if not voltages:
        return None
    own = mechanism.driven_inertia_kgm2(machine)
    document = {
        "parameters": {
            "added_inertia_kgm2": f"inertia:{machine.shaft_joint}_kgm2",
            "voltage_V": "voltage_V",
        },
        "sweep": {
            "added_inertia_kgm2": list(np.linspace(0.0, FLYWHEEL_MULTIPLE * own, FLYWHEEL_STEPS)),
            "voltage_V": list(voltages),
        },
    }
    result = mechanism.sweep(machine, document, duration_s=FLYWHEEL_RUN_S)
    rows = result.table()[1:]  # the grid; row 0 is the nominal machine at the default voltage
    mechanism.write_table(
        out / "flywheel.csv",
        {key: [row[key] for row in rows] for key in rows[0] if key not in ("variant", "note")},
        comments=[
            f"flywheel on {machine.shaft_joint}: added inertia 0-{FLYWHEEL_MULTIPLE:g}x the shaft side's own "
            f"({own:.3g} kg m^2), each run {FLYWHEEL_RUN_S:g} s from rest"
        ],
    )
    mechanism.plot_sweep(result, out / "flywheel.png", x="added_inertia_kgm2", group="voltage_V")
    by_voltage = {}
    for volts in voltages:
        mine = [row for row in rows if row["voltage_V"] == volts]
        bare, biggest = mine[0], mine[-1]
        by_voltage[f"{volts:g}"] = {
            "ripple_pp_rad_s": [bare["ripple_pp_rad_s"], biggest["ripple_pp_rad_s"]],
            "settling_s": [bare["settling_s"], biggest["settling_s"]],
        }
    return {"own_inertia_kgm2": own, "multiple": FLYWHEEL_MULTIPLE, "by_voltage_V": by_voltage}


def _diagnose(machine: mechanism.Machine, out: Path) -> dict:
    recording = out / f"bench_{DEMO_EFFECT}_seed{DEMO_SEED}.csv"
    truth = mechanism.write_bench_recording(
        machine, [DEMO_EFFECT], DEMO_SEED, recording, duration_s=DEMO_RECORDING_S
    )
    # beside the outputs, not in staging
    result = mechanism.diagnose(machine, recording, recording_name=recording.name)
    document = result.to_json()
    (out / "diagnosis.json").write_text(json.dumps(document, indent=2), encoding="utf-8")
    mechanism.diagnosis_report(result, out / "diagnosis")
    return {
        "recording": recording.name,
        "found": [e["name"] for e in document["effects"]],
        "concealed": json.loads(truth.read_text())["effects"],
        "baseline_rmse": document["baseline"]["rmse"],
        "final_rmse": document["final"]["rmse"],
    }


# each step's line says what this machine's section does (a rocker has no revolution, a servo
# arm no sewing run, a machine without described flywheel voltages no flywheel study)
def _tool_step(machine: mechanism.Machine) -> str:
    if not machine.tool_site:
        return "tool motion (none: the description names no tool)"
    return "tool motion over " + (
        "one shaft revolution" if machine.rotates else "the shaft's travel between its stops"
    )


def _simulate_step(machine: mechanism.Machine) -> str:
    kind = machine.description.drive_tables[machine.motor_joint]["type"]
    parts = [
        "steady speeds against measurements" if _steady_speeds_path(machine).is_file() else None,
        "voltage steps" if kind == "dc" else "goal steps",
        "a sewing run" if machine.fabric_capable else None,
    ]
    return "simulate (" + ", ".join(p for p in parts if p) + ")"


def _flywheel_step(machine: mechanism.Machine) -> str:
    if not machine.description.section("inspect").get("flywheel_voltages_V"):
        return "flywheel study (none: the description gives no flywheel voltages)"
    return "flywheel study (speed ripple and settling against added shaft inertia)"


def machine_section(name: str, work: Path, final: Path, step: _Steps) -> dict:
    machine = mechanism.load_machine(name)
    out = work / name
    out.mkdir(parents=True, exist_ok=True)
    facts: dict = {"name": name, "title": machine.description.section("machine").get("name", name)}
    step(f"{name}: convert its CAD export")
    facts["conversion"] = _convert(machine, out, final / name)
    step(f"{name}: {_tool_step(machine)}")
    facts["tool"] = _tool(machine, out)
    step(f"{name}: {_simulate_step(machine)}")
    facts["simulation"] = _simulate(machine, out)
    step(f"{name}: {_flywheel_step(machine)}")
    facts["flywheel"] = _flywheel(machine, out)
    step(f"{name}: probes, clearance with a faulty variant, 3-D animation")
    facts["inspection"] = [p.name for p in mechanism.inspect(machine, out)]
    facts["clearance"] = _clearance_facts(out)
    step(f"{name}: diagnose a virtual bench recording with a concealed {DEMO_EFFECT}")
    facts["diagnosis"] = _diagnose(machine, out)
    return facts


def run(out: str | os.PathLike = "out", machines: list[str] | None = None) -> Path:
    """Run every step for every shipped machine into ``out`` (replaced as a whole at the end)."""
    out = Path(out)
    names = machines or mechanism.shipped_machines()
    step = _Steps(6 * len(names))
    facts = {}
    with mechanism.atomic_dir(out) as work:
        for name in names:
            facts[name] = machine_section(name, work, out, step)
        (work / "demo.json").write_text(
            json.dumps(facts, indent=2, default=float), encoding="utf-8"
        )
        for name, machine_facts in facts.items():
            (work / name / "tour.md").write_text(tour_table(machine_facts), encoding="utf-8")
        (work / "index.html").write_text(_index(facts), encoding="utf-8")
    print(f"wrote {out}/index.html ({time.perf_counter() - step.started:.0f} s)")
    return out / "index.html"


def _clearance_facts(out: Path) -> dict:
    """The clearance step's pairs and how many design variants fail (from the files it wrote)."""
    import csv

    facts: dict = {"pairs": [], "variants": 0, "failing_variants": 0}
    if (out / "clearance.json").is_file():
        document = json.loads((out / "clearance.json").read_text(encoding="utf-8"))
        facts["pairs"] = [
            {"a": p["part_a"], "b": p["part_b"], "min_mm": p["min_distance_mm"]}
            for p in document["pairs"]
        ]
    if (out / "variants.csv").is_file():
        with open(out / "variants.csv", encoding="utf-8") as handle:
            rows = list(csv.DictReader(line for line in handle if not line.startswith("#")))
        facts["variants"], facts["failing_variants"] = (
            len(rows),
            sum(row["pass"] == "0" for row in rows),
        )
    return facts


def tour_table(f: dict) -> str:
    """The README's Tour table for one machine, written from this run's numbers (tour.md beside
    the outputs; a test holds the README to it), so no number in it is typed by hand."""
    name, rows = f["name"], []
    if "counts" in f["conversion"]:
        c = f["conversion"]["counts"]
        rows.append(
            (
                "convert the shipped CAD export",
                f"`{name}/{f['conversion']['mjcf']}` (+ meshes): {c['parts']} parts, {c['bodies']} bodies, "
                f"{c['joints']} joints, {c['loop_closures']} loop closures, {c['couplings']} belt/gear couplings, "
                f"{c['degrees_of_freedom']} degree{'' if c['degrees_of_freedom'] == 1 else 's'} of freedom",
            )
        )
    if f["tool"]:
        t = f["tool"]
        text = f"`tool.csv/png`: {t['stroke_mm']:.3f} mm stroke"
        if t.get("hook_passage_deg") is not None:
            text += (
                f"; the hook point passes the needle {t['needle_rise_at_passage_mm']:.1f} mm above bottom dead centre, "
                f"{t['hook_point_clearance_mm']:.2f} mm clear"
            )
        rows.append(("tool motion", text))
    sim, dynamics = f["simulation"], []
    if sim["steady_speeds"]:
        worst = max(abs(r["error_percent"]) for r in sim["steady_speeds"])
        dynamics.append(
            f"`steady_speeds.csv`: all {len(sim['steady_speeds'])} measured steady speeds within {worst:.1f} %"
        )
    dynamics.append("`simulate_steps.png`")
    if "sewing_mean_rpm" in sim:
        dynamics.append(f"`sewing_12_layers.png` (mean {sim['sewing_mean_rpm']:.0f} rpm at 7 V)")
    rows.append(("dynamics", "; ".join(dynamics)))
    clear = f.get("clearance") or {}
    if clear.get("pairs"):
        pairs = ", ".join(f"{p['a']} vs {p['b']} {p['min_mm']:.2f} mm" for p in clear["pairs"])
        rows.append(
            (
                "probes, clearance",
                f"`probes.csv/png`, `clearance.csv/json`, `variants.csv`: {pairs}; "
                f"{clear['failing_variants']} of {clear['variants']} design variants interfere",
            )
        )
    rows.append(("3-D", "`machine.html`: self-contained meshcat animation, opens offline"))
    d = f["diagnosis"]
    rows.append(
        (
            "diagnosis",
            f"`diagnosis/index.html`, `diagnosis.json`: a virtual bench recording with a concealed "
            f"{', '.join(d['concealed'])}; found {', '.join(d['found']) or 'nothing'}, velocity rmse "
            f"{d['baseline_rmse']:.2g} -> {d['final_rmse']:.2g} rad/s",
        )
    )
    return "| step | what you get |\n| --- | --- |\n" + "".join(
        f"| {step} | {text} |\n" for step, text in rows
    )


def _index(facts: dict) -> str:
    sections = "".join(_section(f) for f in facts.values())
    toc = " &middot; ".join(f'<a href="#{html.escape(n)}">{html.escape(n)}</a>' for n in facts)
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>mechanism demo</title>
<style>body{{font-family:sans-serif;max-width:960px;margin:2em auto;line-height:1.4}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}
pre{{background:#f6f6f6;padding:8px;white-space:pre-wrap}}</style></head><body>
<h1>mechanism demo</h1><p>Every shipped machine, from its CAD export to a diagnosed bench recording: {toc}.
All numbers: <a href="demo.json">demo.json</a>.</p>{sections}</body></html>"""


def _section(f: dict) -> str:
    name = f["name"]

    def link(path, label=None):
        return f'<a href="{html.escape(name)}/{html.escape(path)}">{html.escape(label or path)}</a>'

    def img(path):
        return f'<p><img src="{html.escape(name)}/{html.escape(path)}" style="max-width:900px;width:100%"></p>'

    parts = [
        f'<h2 id="{html.escape(name)}">{html.escape(name)}</h2>',
        f"<h3>CAD export to MuJoCo</h3><pre>{html.escape(chr(10).join(f['conversion']['lines']))}</pre>",
    ]
    if "mjcf" in f["conversion"]:
        parts.append(
            f"<p>{link(f['conversion']['mjcf'], 'converted MJCF')} &middot; {link('machine.html', '3-D animation (opens offline)')}</p>"
        )
    if f["tool"]:
        parts.append(
            f"<h3>Tool motion</h3><pre>{html.escape(chr(10).join(f['tool']['summary']))}</pre>{link('tool.csv')}{img('tool.png')}"
        )
    sim = f["simulation"]
    if sim["steady_speeds"]:
        rows = "".join(
            f"<tr><td>{r['motor_voltage_V']:.2f}</td><td>{r['warm_s']:g}</td><td>{r['measured_rpm']:.0f}</td>"
            f"<td>{r['model_rpm']:.0f}</td><td>{r['error_percent']:+.1f}</td></tr>"
            for r in sim["steady_speeds"]
        )
        parts.append(
            "<h3>Steady speeds against the measurements</h3><table><tr><th>motor V</th><th>warm s</th>"
            f"<th>measured rpm</th><th>model rpm</th><th>error %</th></tr>{rows}</table><p>{link('steady_speeds.csv')}</p>"
        )
    parts.append(
        f"<h3>Voltage steps</h3><p>{link('simulate_steps.csv')}</p>{img('simulate_steps.png')}"
    )
    if "sewing_mean_rpm" in sim:
        parts.append(
            f"<p>Sewing 12 layers at 7 V: mean {sim['sewing_mean_rpm']:.0f} rpm, a dip each time the needle "
            f"pierces. {link('sewing_12_layers.csv')}</p>{img('sewing_12_layers.png')}"
        )
    if f.get("flywheel"):
        fly = f["flywheel"]
        rows = "".join(
            f"<tr><td>{v}</td><td>{d['ripple_pp_rad_s'][0]:.2f}</td><td>{d['ripple_pp_rad_s'][1]:.2f}</td>"
            f"<td>{d['settling_s'][0]:.2f}</td><td>{d['settling_s'][1]:.2f}</td></tr>"
            for v, d in fly["by_voltage_V"].items()
        )
        parts.append(
            f"<h3>A bigger flywheel?</h3><p>Inertia added on the shaft, up to {fly['multiple']:g}x the shaft side's own "
            f"({fly['own_inertia_kgm2']:.3g} kg m&sup2;): the speed ripple falls, the start takes longer.</p>"
            "<table><tr><th>motor V</th><th>ripple p-p rad/s, bare</th><th>with flywheel</th><th>settling s, bare</th>"
            f"<th>with flywheel</th></tr>{rows}</table><p>{link('flywheel.csv')}</p>{img('flywheel.png')}"
        )
    if f["inspection"]:
        parts.append(
            "<h3>Probes and clearance</h3><p>"
            + " &middot; ".join(link(p) for p in f["inspection"] if not p.endswith(".png"))
            + "</p>"
        )
        parts += [img(p) for p in f["inspection"] if p.endswith(".png")]
    d = f["diagnosis"]
    parts.append(
        f"<h3>Diagnosis of a bench recording</h3><p>{link(d['recording'])}: concealed {', '.join(d['concealed']) or 'nothing'}; "
        f"found {', '.join(d['found']) or 'nothing'}; velocity rmse {d['baseline_rmse']:.3f} -> {d['final_rmse']:.3f} rad/s. "
        f"{link('diagnosis/index.html', 'report')} &middot; {link('diagnosis.json')}</p>"
    )
    return "".join(parts)
