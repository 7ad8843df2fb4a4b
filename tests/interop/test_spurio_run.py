"""`spurio run` as a command among FMI tools: recording off or thinned (as OMSimulator's and
fmpy's result options), SSP archives unpacked into a temporary folder, errors that name the
archive once and say what is supported."""

import os
import subprocess
import zipfile

from conftest import REFERENCE_FMUS, SPURIO, read_csv, spurio


def stair_system(workdir):
    path = workdir / "stair.toml"
    path.write_text(
        "stop_time = 10.0\nstep_size = 0.2\n"
        f'[[instance]]\nname = "stair"\nfmu = "{REFERENCE_FMUS / "Stair.fmu"}"\n'
    )
    return path


def test_no_record_writes_nothing(workdir):
    run = spurio("run", stair_system(workdir), "--no-record", "--out", workdir / "x.csv",
                 check=False)
    assert run.returncode != 0 and "cannot be used with" in run.stderr
    result = subprocess.run(
        [str(SPURIO), "run", str(stair_system(workdir)), "--no-record"],
        capture_output=True, text=True, cwd=workdir,
    )
    assert result.returncode == 0, result.stderr
    assert "wrote" not in result.stdout
    assert sorted(p.name for p in workdir.iterdir()) == ["stair.toml"]


def test_an_output_interval_records_every_kth_point_and_the_last(workdir):
    spurio("run", stair_system(workdir), "--out", workdir / "all.csv")
    spurio("run", stair_system(workdir), "--out", workdir / "k.csv", "--output-interval", "4")
    _, every = read_csv(workdir / "all.csv")
    _, thinned = read_csv(workdir / "k.csv")
    # Stair ends at t = 9 (point 45): points 0, 4, …, 44 and the last one.
    assert [round(t, 9) for t in thinned[:, 0]] == [round(0.8 * i, 9) for i in range(12)] + [9.0]
    assert (thinned[:-1] == every[:-1:4]).all() and (thinned[-1] == every[-1]).all()
    bad = spurio("run", stair_system(workdir), "--output-interval", "0", check=False)
    assert bad.returncode != 0


def export_crane_sensor(workdir):
    from test_ssp import export

    return export(workdir, "2.0")


def test_an_ssp_is_unpacked_into_a_temporary_folder_and_removed(workdir):
    ssp = export_crane_sensor(workdir)
    tmp = workdir / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    result = subprocess.run(
        [str(SPURIO), "run", str(ssp), "--out", str(workdir / "r.csv")],
        capture_output=True, text=True, env=env,
    )
    assert result.returncode == 0, result.stderr
    assert "step size 0.0078125 from the org.spurio.simulation annotation" in result.stderr
    assert list(tmp.iterdir()) == []
    assert not (workdir / f"{ssp.name}.d").exists()
    keep = workdir / "kept"
    spurio("run", ssp, "--out", workdir / "r.csv", "--unpack-to", keep)
    assert sorted(p.name for p in (keep / "resources").iterdir()) == [
        "GantryCrane.fmu",
        "Sensor2.fmu",
    ]


def broken_copy(ssp, old: bytes, new: bytes):
    with zipfile.ZipFile(ssp) as z:
        entries = {n: z.read(n) for n in z.namelist()}
    assert old in entries["SystemStructure.ssd"]
    entries["SystemStructure.ssd"] = entries["SystemStructure.ssd"].replace(old, new, 1)
    bad = ssp.parent / "bad.ssp"
    with zipfile.ZipFile(bad, "w") as z:
        for n, data in entries.items():
            z.writestr(n, data)
    return bad


def test_an_ssp_error_names_the_archive_once(workdir):
    ssp = export_crane_sensor(workdir)
    for old, new, said in [
        (b'version="2.0" name=', b'version="3.0" name=',
         "bad.ssp: SystemStructure.ssd: SSP version `3.0` is not supported (1.0 and 2.0 are)"),
        (b'startConnector="x"', b'startConnector="xx"',
         "bad.ssp: instance `crane` (resources/GantryCrane.fmu): no variable `xx`"),
    ]:
        result = spurio("run", broken_copy(ssp, old, new), check=False)
        assert result.returncode != 0
        assert result.stderr.count("bad.ssp") == 1, result.stderr
        assert said in result.stderr, result.stderr


def test_a_string_parameter_says_what_is_supported(workdir):
    system = workdir / "ft.toml"
    system.write_text(
        "stop_time = 1.0\nstep_size = 0.1\n"
        f'[[instance]]\nname = "ft"\nfmu = "{REFERENCE_FMUS / "Feedthrough.fmu"}"\n'
        'parameters = { String_input = "abc" }\n'
    )
    result = spurio("run", system, check=False)
    assert result.returncode != 0
    assert (
        "parameter `String_input`: is of type String, and only Real, Integer, Enumeration "
        'and Boolean variables can be given values (the value was `"abc"`)'
    ) in result.stderr
