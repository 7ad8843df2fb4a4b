"""Every FMU of build/fmus carries the three platforms (scripts/build-fmus): fmpy lists
`linux64` and `win64` among its supported platforms, `binaries/aarch64-linux/<Id>.so` is an
AArch64 ELF shared object (read from its header bytes: fmpy does not report that FMI 3.0
platform tuple for an FMI 2.0 FMU), it validates in fmpy and simulates on linux64.

A host-only build (`scripts/build-fmus --host-only`, SPURIO_HOST_ONLY=1) skips these checks."""

import os
import struct
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu, supported_platforms
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, REPO

# The bundled FMUs: one committed model description each (a variant packaged by a user
# into build/fmus is not one of them).
FMUS = [FMU_DIR / f"{p.stem}.fmu" for p in sorted((REPO / "modelDescription").glob("*.xml"))]
ELF_MACHINE_AARCH64 = 183  # EM_AARCH64
ELF_MACHINE_X86_64 = 62  # EM_X86_64

pytestmark = pytest.mark.skipif(
    os.environ.get("SPURIO_HOST_ONLY") == "1", reason="host-only build (SPURIO_HOST_ONLY=1)"
)


def elf_header(data: bytes) -> tuple[int, int, int, int]:
    """(class, data encoding, type, machine) of an ELF header; class 2 = 64-bit, encoding
    1 = little-endian, type 3 = shared object."""
    assert data[:4] == b"\x7fELF", "not an ELF file"
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    return data[4], data[5], e_type, e_machine


def test_all_bundled_fmus_are_there():
    assert len(FMUS) == 25, [p.name for p in FMUS]
    missing = [p.name for p in FMUS if not p.is_file()]
    assert not missing, f"not in {FMU_DIR}: {missing} (scripts/build-fmus)"


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: p.stem)
def test_three_platforms_inside(fmu):
    platforms = supported_platforms(str(fmu))
    assert "linux64" in platforms and "win64" in platforms, platforms
    ident = read_model_description(str(fmu)).coSimulation.modelIdentifier
    with zipfile.ZipFile(fmu) as z:
        arm = z.read(f"binaries/aarch64-linux/{ident}.so")
        x64 = z.read(f"binaries/linux64/{ident}.so")
        dll = z.read(f"binaries/win64/{ident}.dll")
    assert elf_header(arm) == (2, 1, 3, ELF_MACHINE_AARCH64)
    assert elf_header(x64) == (2, 1, 3, ELF_MACHINE_X86_64)
    # PE32+ for x86-64: "MZ", the PE header at e_lfanew, machine 0x8664, DLL flag.
    assert dll[:2] == b"MZ"
    pe = struct.unpack_from("<I", dll, 0x3C)[0]
    assert dll[pe : pe + 4] == b"PE\0\0"
    machine, _, _, _, _, _, characteristics = struct.unpack_from("<HHIIIHH", dll, pe + 4)
    assert machine == 0x8664 and characteristics & 0x2000


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: p.stem)
def test_validates_and_simulates_on_linux64(fmu):
    assert validate_fmu(str(fmu)) == []
    de = read_model_description(str(fmu)).defaultExperiment
    result = simulate_fmu(str(fmu), start_time=float(de.startTime), stop_time=float(de.stopTime),
                          output_interval=float(de.stepSize))
    steps = round((float(de.stopTime) - float(de.startTime)) / float(de.stepSize))
    assert len(result) == steps + 1
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name].astype(float))), name
