"""Campaign loading and `frictionuq ingest`: SI conversion, ARTS JSON records, and every kind of
bad input refused with exit code 2, one line naming the file and row/key, and --out untouched."""
import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import frictionuq as fq
from frictionuq import units as U
from frictionuq.cli import main

ROOT = Path(__file__).resolve().parents[1]

TOML = """name = "mini"
device = "test rig"
[units]
time = "{time}"
displacement = "{disp}"
force = "{force}"
applied = "{applied}"
{extra}
[[tests]]
id = "h1"
file = "tests/h1.csv"
applied = 10
kind = "harmonic"
frequency_hz = 0.5

[[tests]]
id = "h2"
file = "tests/h2.csv"
applied = 20
"""


def _csv(n=50, scale=1.0, applied=True, header="time,displacement,force", t0=0.0):
    t = t0 + np.arange(n) * 0.01
    x = 10 * np.sin(2 * np.pi * 0.5 * t)
    f = scale * np.cos(2 * np.pi * 0.5 * t)
    cols = [t, x, f]
    if applied:
        header += ",applied"
        cols.append(np.full(n, 10.0))
    lines = [header] + [",".join(f"{v:.17g}" for v in row) for row in zip(*cols)]
    return "\n".join(lines) + "\n"


def make_campaign(root: Path, time="s", disp="mm", force="kN", applied="N", extra="", files=None):
    root.mkdir(parents=True, exist_ok=True)
    (root / "tests").mkdir(exist_ok=True)
    (root / "campaign.toml").write_text(TOML.format(time=time, disp=disp, force=force,
                                                     applied=applied, extra=extra))
    files = files or {}
    for name in ("h1", "h2"):
        (root / "tests" / f"{name}.csv").write_text(files.get(name, _csv()))
    return root


def run_cli(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ----------------------------------------------------------------------------- good input

def test_load_converts_to_si(tmp_path):
    camp = fq.load_campaign(make_campaign(tmp_path / "c", time="ms", disp="in", force="kip", applied="psi"))
    t1 = camp.test("h1")
    raw = np.loadtxt(tmp_path / "c/tests/h1.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(t1.record.t, raw[:, 0] * 1e-3)
    np.testing.assert_allclose(t1.record.x, raw[:, 1] * 0.0254)
    np.testing.assert_allclose(t1.record.force, raw[:, 2] * 4448.2216152605)
    np.testing.assert_allclose(t1.record.applied, raw[:, 3] * 6894.757293168361)
    assert t1.applied == pytest.approx(10 * 6894.757293168361)
    assert camp.applied_si_unit == "Pa"
    assert t1.kind == "harmonic" and t1.frequency_hz == 0.5
    assert camp.test("h2").kind == "other"
    assert len(t1.sha256) == 64


def test_columns_mapping(tmp_path):
    hdr = "Time (sec),Axial Displacement (in),Axial Force (kip)"
    extra = '[columns]\ntime = "Time (sec)"\ndisplacement = "Axial Displacement (in)"\nforce = "Axial Force (kip)"\n'
    c = make_campaign(tmp_path / "c", extra=extra,
                      files={"h1": _csv(header=hdr, applied=False), "h2": _csv(header=hdr, applied=False)})
    camp = fq.load_campaign(c)
    assert camp.test("h1").record.applied is None
    assert camp.test("h2").record.n == 50


def test_ingest_round_trip(tmp_path, capsys):
    c = make_campaign(tmp_path / "c")
    out = tmp_path / "out"
    code, so, se = run_cli(["ingest", str(c), "--out", str(out)], capsys)
    assert code == 0, se
    m = json.loads((out / "manifest.json").read_text())
    assert m["package_version"] == fq.__version__ and m["environment"]["packages"]["numpy"]
    assert m["units"] == {"time": "s", "displacement": "m", "force": "N", "applied": "N"}
    assert [t["id"] for t in m["tests"]] == ["h1", "h2"]
    assert all(len(t["source_sha256"]) == 64 for t in m["tests"])
    a = fq.load_campaign(c)
    b = fq.load_campaign(out)
    assert b.ingested
    for ta, tb in zip(a.tests, b.tests):
        for k in ("t", "x", "force", "applied"):       # every value exactly (17 digits)
            np.testing.assert_array_equal(getattr(tb.record, k), getattr(ta.record, k))
        assert ta.applied == tb.applied
    # times of an absolute clock keep their fraction (at 10 digits 1733400000.01 s became
    # 1733400000 s, and every later command refused the ingested folder)
    clock = make_campaign(tmp_path / "clock", files={"h1": _csv(t0=1733400000.0)})
    assert run_cli(["ingest", str(clock), "--out", str(tmp_path / "clock-in")], capsys)[0] == 0
    np.testing.assert_array_equal(fq.load_campaign(tmp_path / "clock-in").test("h1").record.t,
                                  fq.load_campaign(clock).test("h1").record.t)
    # a corrupted file of the ingested folder is detected by its hash
    f = out / "tests/h1.csv"
    f.write_text(f.read_text().replace("0.01,", "0.011,", 1))
    with pytest.raises(ValueError, match="SHA-256"):
        fq.load_campaign(out)


@pytest.mark.parametrize("edit,fragment", [
    (lambda m: m.pop("name"), "key name: missing is not a valid value"),
    (lambda m: m.update(tests={"h1": {}}), "key tests: {'h1': {}} is not a valid value"),
    (lambda m: m["tests"][0].pop("id"), "tests[0], key id: missing"),
    (lambda m: m["tests"][1].pop("file"), "tests[1], key file: missing"),
    (lambda m: m["tests"][0].update(applied="x"), "tests[0], key applied: 'x' is not a valid value"),
    (lambda m: m["tests"].__setitem__(1, "h2"), "key tests[1]: 'h2' is not a valid value"),
])
def test_a_hand_edited_manifest_is_named_not_a_traceback(tmp_path, capsys, edit, fragment):
    """An ingested folder is a campaign every command takes; its manifest edited by hand (a key
    deleted, a wrong type) gave KeyError or TypeError tracebacks, or "could not convert string to
    float: 'x'" without the file or key, until 2026-12-05."""
    c = make_campaign(tmp_path / "c")
    out = tmp_path / "in"
    assert run_cli(["ingest", str(c), "--out", str(out)], capsys)[0] == 0
    mp = out / "manifest.json"
    m = json.loads(mp.read_text())
    edit(m)
    mp.write_text(json.dumps(m))
    code, _, se = run_cli(["table", str(out)], capsys)
    assert code == 2 and se.count("\n") == 1 and "Traceback" not in se, se
    assert f"{mp}, {fragment}" in se and "ingest the campaign again" in se, se


def _arts_json(n=40, units=None, applied=(50.0, -30.0)):
    t = np.arange(n) / 1024
    rows = [[float(tt), 0.5 * np.sin(tt * 6), 0.1 * np.cos(tt * 6), 0.0, applied[0] * (i % 2),
             applied[1] * ((i + 1) % 2)] for i, tt in enumerate(t)]
    d = {"data": rows, "dt": 1 / 1024, "sampling freq": 1024, "displacement units": "in",
         "time units": "s", "friction force units": "kip", "actuator force units": "lb"}
    d.update(units or {})
    return d


def make_arts_campaign(root: Path, doc=None, gz=True, units_applied="lb"):
    root.mkdir(parents=True, exist_ok=True)
    name = "r.json.gz" if gz else "r.json"
    data = json.dumps(doc if doc is not None else _arts_json()).encode()
    (root / name).write_bytes(gzip.compress(data) if gz else data)
    (root / "campaign.toml").write_text(
        f'name = "arts"\n[units]\ntime = "s"\ndisplacement = "in"\nforce = "kip"\napplied = "{units_applied}"\n'
        f'[[tests]]\nid = "r"\nfile = "{name}"\napplied = 36\nkind = "harmonic"\nfrequency_hz = 1\n')
    return root


@pytest.mark.parametrize("gz", [True, False])
def test_arts_json_record(tmp_path, gz):
    camp = fq.load_campaign(make_arts_campaign(tmp_path / "a", gz=gz))
    r = camp.tests[0].record
    d = _arts_json()
    a = np.array(d["data"])
    np.testing.assert_allclose(r.x, a[:, 1] * U.INCH)
    np.testing.assert_allclose(r.force, a[:, 2] * 1e3 * U.LBF)
    # measured applied force: |F_act1| + |F_act2|, lb -> N
    np.testing.assert_allclose(r.applied, (np.abs(a[:, 4]) + np.abs(a[:, 5])) * U.LBF)
    assert camp.tests[0].applied == pytest.approx(36 * U.LBF)


# ----------------------------------------------------------------------------- bad input

def _bad_cases():
    """(name, builder(root) -> campaign path, expected message fragments)."""
    def csv_with(cell_row, col, value):
        lines = _csv().splitlines()
        cells = lines[cell_row].split(",")
        cells[col] = value
        lines[cell_row] = ",".join(cells)
        return "\n".join(lines) + "\n"

    def toml_edit(old, new):
        def b(r):
            c = make_campaign(r)
            p = c / "campaign.toml"
            p.write_text(p.read_text().replace(old, new, 1))
            return c
        return b

    def file_case(content):
        return lambda r: make_campaign(r, files={"h2": content})

    def no_toml(r):
        c = make_campaign(r)
        (c / "campaign.toml").unlink()
        return c

    def arts(doc=None, units_applied="lb"):
        return lambda r: make_arts_campaign(r, doc=doc, units_applied=units_applied)

    def gz_record(data: bytes):
        """h2's record as tests/h2.csv.gz holding `data` (a damaged or truncated gzip file)."""
        def b(r):
            c = toml_edit("tests/h2.csv", "tests/h2.csv.gz")(r)
            (c / "tests" / "h2.csv.gz").write_bytes(data)
            return c
        return b

    def latin1(r):
        """h2 with an extra text column whose line 8 holds a Latin-1 micro sign."""
        c = make_campaign(r)
        lines = _csv().splitlines()
        rows = [lines[0] + ",note"] + [ln + (",\xb5m" if i == 8 else ",ok") for i, ln in
                                       enumerate(lines[1:], 2)]
        (c / "tests" / "h2.csv").write_bytes(("\n".join(rows) + "\n").encode("latin-1"))
        return c

    def with_bom(r):
        c = make_campaign(r)
        p = c / "campaign.toml"
        p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
        return c

    return [
        ("missing campaign.toml", no_toml, ["campaign.toml", "missing"]),
        ("unparsable toml", toml_edit('name = "mini"', 'name = "mini'), ["campaign.toml", "not valid TOML"]),
        ("wrong type", toml_edit("applied = 20", 'applied = "twenty"'), ["tests[1]", "applied", "expected a number"]),
        ("missing key", toml_edit('file = "tests/h2.csv"', ""), ["tests[1]", "missing key 'file'"]),
        ("unknown key", toml_edit("kind = ", "knd = "), ["tests[0]", "unknown key 'knd'"]),
        ("bad kind", toml_edit('kind = "harmonic"', 'kind = "sine"'), ["tests[0]", "kind", "'sine'"]),
        ("missing file", toml_edit("tests/h2.csv", "tests/nope.csv"), ["tests[1]", "nope.csv", "not found"]),
        ("missing column", file_case(_csv(header="time,disp,force")), ["h2.csv", "missing column 'displacement'"]),
        ("semicolons", file_case(_csv().replace(",", ";")), ["h2.csv", "missing column 'time'",
                                                            "looks ';'-separated"]),
        ("non-numeric cell", file_case(csv_with(7, 2, "abc")), ["h2.csv", "line 8", "force", "'abc' is not a number"]),
        # a row with a value too many: until 2026-12-05 pandas' "Error tokenizing data. C error"
        ("extra value", file_case(csv_with(5, 2, "1.0,7")),
         ["h2.csv, line 6: 5 values, but the header names 4 columns", "remove the extra values"]),
        ("empty cell", file_case(csv_with(5, 1, "")), ["h2.csv", "line 6", "displacement", "empty cell"]),
        ("NaN", file_case(csv_with(9, 2, "nan")), ["h2.csv", "line 10", "NaN"]),
        ("inf", file_case(csv_with(11, 1, "inf")), ["h2.csv", "line 12", "not finite"]),
        ("time not increasing", file_case(csv_with(20, 0, "0.05")), ["h2.csv", "line 21", "not strictly increasing"]),
        ("duplicated id", toml_edit('id = "h2"', 'id = "h1"'), ["tests[1]", "duplicated test id 'h1'"]),
        ("two quantities from one column", toml_edit('\n[[tests]]', '[columns]\ndisplacement = "time"\n[[tests]]'),
         ["[columns]", "time and displacement are both read from column 'time'"]),
        ("unknown unit", toml_edit('force = "kN"', 'force = "tonnes"'), ["units.force", "'tonnes'"]),
        ("too few samples", file_case(_csv(n=9)), ["h2.csv", "9 samples", "at least 10"]),
        # until 2026-12-05 a traceback (gzip.BadGzipFile, EOFError) and exit 1
        ("not gzip", gz_record(b"notgzip\n"), ["h2.csv.gz", "not a readable compressed file"]),
        ("truncated gzip", gz_record(gzip.compress(_csv(n=400).encode())[:900]),
         ["h2.csv.gz", "not a readable compressed file"]),
        # finite in the file, inf in SI (1e308 kN): until 2026-12-05 accepted as inf
        ("overflow in SI", file_case(csv_with(7, 2, "1e308")),
         ["h2.csv", "data row 7, force: 1e+308 kN overflows when converted to SI"]),
        ("BOM", with_bom, ["campaign.toml", "not valid TOML", "byte-order mark (BOM)"]),
        # a Latin-1 byte: pandas named "position 3" of its buffer, no line (until 2026-12-05)
        ("latin-1", latin1, ["h2.csv, line 8: not UTF-8 text; save the file as UTF-8"]),
        ("empty file", file_case(""), ["h2.csv", "empty"]),
        ("json unit contradicts", arts(_arts_json(units={"displacement units": "mm"})),
         ["r.json.gz", "displacement unit 'mm'", "units.displacement = 'in'"]),
        ("json applied unit contradicts", arts(units_applied="psi"), ["r.json.gz", "applied unit 'lb'", "'psi'"]),
        ("json too few samples", arts(_arts_json(n=5)), ["r.json.gz", "5 samples"]),
        ("json non-numeric", arts({**_arts_json(), "data": _arts_json()["data"][:20] + [[0.1, "x", 0, 0, 0, 0]] * 3}),
         ["r.json.gz", "row 20", 'column 1 (x [in]): "x" is not a number']),
        # a JSON null: until 2026-12-05 "column x: nan is not finite" (null read as NaN)
        ("json null", arts({**_arts_json(), "data": _arts_json()["data"][:20] + [[0.1, 0, None, 0, 0, 0]] * 3}),
         ["r.json.gz", "row 20", "column 2 (F friction force [kip]): null is not a number"]),
        ("json missing key", arts({k: v for k, v in _arts_json().items() if k != "time units"}),
         ["r.json.gz", "missing key 'time units'"]),
    ]


@pytest.mark.parametrize("name,build,fragments", _bad_cases(), ids=[c[0] for c in _bad_cases()])
def test_bad_input_refused(tmp_path, capsys, name, build, fragments):
    camp = build(tmp_path / "camp")
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text('{"format": "frictionuq-ingested/1", "keep": true}')
    (out / "tests").mkdir()
    (out / "tests" / "old.csv").write_text("previous output\n")
    before = snapshot(out)
    code, so, se = run_cli(["ingest", str(camp), "--out", str(out)], capsys)
    assert code == 2
    lines = se.strip().splitlines()
    assert len(lines) == 1, se
    assert lines[0].startswith("frictionuq: error: ")
    for frag in fragments:
        assert frag in lines[0], (frag, lines[0])
    assert "Traceback" not in se
    assert snapshot(out) == before              # nothing lost or half-written
    assert sorted(p.name for p in out.parent.iterdir()) == ["camp", "out"]   # no temp leftovers


def test_refuses_to_replace_foreign_folder(tmp_path, capsys):
    c = make_campaign(tmp_path / "c")
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("precious")
    code, _, se = run_cli(["ingest", str(c), "--out", str(out)], capsys)
    assert code == 2 and "not empty" in se
    assert (out / "notes.txt").read_text() == "precious"


def test_console_script_error_has_no_traceback(tmp_path):
    """The installed entry point prints one line and exits 2 (not only main())."""
    exe = Path(sys.executable).with_name("frictionuq")
    r = subprocess.run([str(exe), "ingest", str(tmp_path / "nothing"), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "nothing" in r.stderr and "Traceback" not in r.stderr


# ----------------------------------------------------------------------------- shipped real data

@pytest.mark.parametrize("name,n_tests", [("brfd-arts-d1", 12), ("brfd-arts-d2", 17)])
def test_shipped_arts_campaigns(name, n_tests):
    camp = fq.load_campaign(ROOT / "data" / name)
    assert len(camp.tests) == n_tests
    assert camp.units == {"time": "s", "displacement": "in", "force": "kip", "applied": "lb"}
    readme = (ROOT / "data" / name / "README.md").read_text()
    assert "CC BY-SA 4.0" in readme
    for te in camp.tests:
        r = te.record
        assert r.rate_hz == pytest.approx(1024.0)
        assert r.applied is not None and np.all(r.applied >= 0)
        assert 5e-3 < np.ptp(r.x) < 0.1                 # tens of mm of stroke
        assert 1e3 < np.ptp(r.force) < 6e4               # kN-scale friction force
        # the shipped file is the upstream file, gzip-compressed unchanged
        raw = gzip.open(camp.path / te.file).read()
        import hashlib
        assert hashlib.sha256(raw).hexdigest() in readme
    levels_lb = sorted({round(U.from_si(t.applied, "applied", "lb")) for t in camp.tests})
    assert levels_lb == ([20, 22, 25, 35, 70, 80] if name.endswith("d1") else [0, 36])


def test_geometry_is_written_in_the_same_order_in_every_process():
    """The geometry keys were a set, so manifest.json and advantage.json wrote them in an order
    that followed each process's string-hash seed: the same campaign gave other bytes (and a
    stale pipeline task after a forced re-ingest). Two processes with different hash seeds."""
    import os
    code = ("import json; from frictionuq.campaign import parse_config; "
            "d = {'name': 'g', 'units': {'time': 's', 'displacement': 'm', 'force': 'N', "
            "'applied': 'N'}, 'geometry': {'C_design': 142.0, 'wrap_deg': 670.0, "
            "'drum_radius': 0.15, 'damping_radius': 0.1, 'mu_design': 0.39}, "
            "'tests': [{'id': 'a', 'file': 'a.csv', 'applied': 1.0, 'kind': 'harmonic'}]}; "
            "print(json.dumps(parse_config(d, 'x.toml')['geometry']))")
    outs = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": str(h)}).stdout for h in (1, 2, 3, 4)}
    assert len(outs) == 1, outs
    assert list(json.loads(outs.pop())) == ["drum_radius", "damping_radius", "wrap_deg",
                                            "mu_design", "C_design"]


def test_table_flags_a_stroke_no_damper_test_has(tmp_path, capsys):
    """Millimetres declared as metres load as a 20 m stroke; the table says so under the rows
    (frictionuq.quality), before anyone fits it."""
    camp = make_campaign(tmp_path / "c", disp="m")            # the CSVs hold +-10 (mm)
    code, out, _ = run_cli(["table", str(camp)], capsys)
    assert code == 0
    assert "flags: h1:" in out and "check the campaign's displacement unit" in out
    code, out, _ = run_cli(["table", str(make_campaign(tmp_path / "ok"))], capsys)
    assert code == 0 and "displacement unit" not in out


# ------------------------------------------------------------------ a Campaign built in memory

def _hand_built(**record):
    from frictionuq.campaign import Campaign, Record, Test
    t = np.arange(400) / 100.0
    arrays = {"t": t, "x": 0.01 * np.sin(np.pi * t), "force": 1e3 * np.cos(np.pi * t)}
    arrays.update(record)
    rec = None if record.get("t", 0) is None else Record(arrays["t"], arrays["x"], arrays["force"],
                                                         arrays.get("applied"))
    return Campaign(name="nb", path=Path("."), units={"time": "s", "displacement": "m",
                                                      "force": "N", "applied": "N"},
                    tests=[Test(id="a", file="a.csv", applied=100.0, kind="harmonic", record=rec)])


def _with(**change):
    t = np.arange(400) / 100.0
    out = {}
    for k, v in change.items():
        out[k] = v(t) if callable(v) else v
    return out


@pytest.mark.parametrize("record,fragment", [
    ({"force": lambda t: np.where(np.arange(t.size) == 5, np.nan, 1.0)},
     "test 'a': record.force has 1 NaN or infinite sample(s), the first at index 5"),
    ({"x": lambda t: np.zeros(t.size - 1)}, "test 'a': record.x has 399 samples, record.t has 400"),
    ({"t": lambda t: np.where(np.arange(t.size) == 10, t[9], t)},
     "record.t, index 10: time is not strictly increasing"),
    ({"applied": lambda t: np.ones((t.size, 2))}, "record.applied must be 1-D, got shape (400, 2)"),
    ({"x": lambda t: ["a"] * t.size}, "record.x is not an array of numbers"),
    ({"t": None}, "test 'a': no record (expected a Record of SI arrays t, x, force), got nothing"),
])
def test_fit_campaign_checks_a_campaign_built_in_memory(tmp_path, record, fragment):
    """fit_campaign given a Campaign object (a notebook's arrays, never read from files) checks
    it as load_campaign checks files, before any work, and names the test, the array and the
    first bad sample (before: a NaN force or a repeated time gave 'no sliding plateaus', arrays of
    unequal length a numpy error from inside the prior builder, no record an AttributeError)."""
    from frictionuq.errors import InputError
    from frictionuq.infer.fit import fit_campaign
    with pytest.raises(InputError, match=None) as e:
        fit_campaign(_hand_built(**_with(**record)), tmp_path / "out")
    assert str(e.value).startswith("campaign 'nb', test 'a'") and fragment in str(e.value)
    assert not (tmp_path / "out").exists()


def test_campaigns_loaded_from_files_pass_the_in_memory_check():
    """Whatever load_campaign returns passes check_campaign (the two checks agree), and so does a
    well-formed hand-built campaign; a negative applied force or a bad id is refused."""
    from dataclasses import replace
    from frictionuq.campaign import check_campaign
    from frictionuq.errors import InputError
    for name in ("brfd-twin", "mfd-twin", "brfd-arts-d2"):
        check_campaign(fq.load_campaign(ROOT / "data" / name))
    good = _hand_built()
    check_campaign(good)
    for change, fragment in (({"applied": -5.0}, "applied must be a finite number >= 0 (SI), got -5.0"),
                             ({"id": "a b"}, "'a b' is not a valid test id"),
                             ({"kind": "sine"}, "kind 'sine' is not one of harmonic")):
        bad = replace(good, tests=[replace(good.tests[0], **change)])
        with pytest.raises(InputError, match=None) as e:
            check_campaign(bad)
        assert fragment in str(e.value)
    with pytest.raises(InputError, match="duplicated test id 'a'"):
        check_campaign(replace(good, tests=good.tests * 2))
