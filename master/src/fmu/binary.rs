//! What the FMU's shared library is, read from its bytes before it is loaded: the file
//! format and architecture (so a library for another platform is named as such instead of
//! failing with the loader's "No such file or directory"), and the fmi2/fmi3 functions it exports
//! (so a missing entry point is reported here instead of failing inside rust-fmi at the
//! first call). Only the headers and the dynamic symbol table are parsed, with `object`.

use object::{Architecture, BinaryFormat, FileKind, Object, ObjectKind};

/// Every function FMI 2.0 requires of a Co-Simulation FMU: the common functions and those
/// of the Co-Simulation interface (an FMU that does not support one still exports it and
/// returns fmi2Error).
pub const REQUIRED_FUNCTIONS: [&str; 34] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
];

/// Every function FMI 3.0 requires of a Co-Simulation FMU: the common functions (FMI 3.0
/// §2.3; an FMU without a capability still exports the function and returns fmi3Error) and
/// those of the Co-Simulation interface (§4.2).
pub const REQUIRED_FUNCTIONS_3: [&str; 62] = [
    "fmi3GetVersion",
    "fmi3SetDebugLogging",
    "fmi3InstantiateCoSimulation",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3EnterEventMode",
    "fmi3Terminate",
    "fmi3Reset",
    "fmi3GetFloat32",
    "fmi3GetFloat64",
    "fmi3GetInt8",
    "fmi3GetUInt8",
    "fmi3GetInt16",
    "fmi3GetUInt16",
    "fmi3GetInt32",
    "fmi3GetUInt32",
    "fmi3GetInt64",
    "fmi3GetUInt64",
    "fmi3GetBoolean",
    "fmi3GetString",
    "fmi3GetBinary",
    "fmi3GetClock",
    "fmi3SetFloat32",
    "fmi3SetFloat64",
    "fmi3SetInt8",
    "fmi3SetUInt8",
    "fmi3SetInt16",
    "fmi3SetUInt16",
    "fmi3SetInt32",
    "fmi3SetUInt32",
    "fmi3SetInt64",
    "fmi3SetUInt64",
    "fmi3SetBoolean",
    "fmi3SetString",
    "fmi3SetBinary",
    "fmi3SetClock",
    "fmi3GetNumberOfVariableDependencies",
    "fmi3GetVariableDependencies",
    "fmi3GetFMUState",
    "fmi3SetFMUState",
    "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState",
    "fmi3GetDirectionalDerivative",
    "fmi3GetAdjointDerivative",
    "fmi3EnterConfigurationMode",
    "fmi3ExitConfigurationMode",
    "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction",
    "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction",
    "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction",
    "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction",
    "fmi3EvaluateDiscreteStates",
    "fmi3UpdateDiscreteStates",
    "fmi3EnterStepMode",
    "fmi3GetOutputDerivatives",
    "fmi3DoStep",
];

/// Whether `function` belongs to the Co-Simulation interface only (of [`REQUIRED_FUNCTIONS`]
/// and [`REQUIRED_FUNCTIONS_3`]: stepping, its status and input/output derivatives, FMI 3.0's
/// Co-Simulation instantiation and step mode); the others are common to both interfaces.
fn co_simulation_only(function: &str) -> bool {
    [
        "DoStep",
        "CancelStep",
        "Status",
        "InputDerivatives",
        "OutputDerivatives",
        "InstantiateCoSimulation",
        "StepMode",
    ]
    .iter()
    .any(|part| function.contains(part))
}

/// The functions of the Model Exchange interface, FMI 2.0 (§3.2) and FMI 3.0 (§3.2).
const MODEL_EXCHANGE_ONLY: [&str; 21] = [
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
    "fmi3InstantiateModelExchange",
    "fmi3EnterContinuousTimeMode",
    "fmi3CompletedIntegratorStep",
    "fmi3SetTime",
    "fmi3SetContinuousStates",
    "fmi3GetContinuousStateDerivatives",
    "fmi3GetEventIndicators",
    "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfContinuousStates",
];

/// Every function FMI 2.0 (`fmi3`: false) or FMI 3.0 requires of a Model Exchange FMU: the
/// common ones and those of the Model Exchange interface.
pub fn required_model_exchange(fmi3: bool) -> Vec<&'static str> {
    let (all, prefix): (&[&'static str], &str) = if fmi3 {
        (&REQUIRED_FUNCTIONS_3, "fmi3")
    } else {
        (&REQUIRED_FUNCTIONS, "fmi2")
    };
    all.iter()
        .copied()
        .filter(|f| !co_simulation_only(f))
        .chain(
            MODEL_EXCHANGE_ONLY
                .iter()
                .copied()
                .filter(|f| f.starts_with(prefix)),
        )
        .collect()
}

/// Why a library cannot be used on this machine.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LibraryProblem {
    /// The file is not a shared library for this platform; the text says what it is.
    WrongKind { found: String, expected: String },
    /// Required functions are not exported.
    MissingFunctions(Vec<&'static str>),
}

/// The library format this machine loads, e.g. "an ELF shared library for x86_64".
pub fn expected_kind() -> String {
    format!(
        "{} for {} ({} {})",
        if cfg!(windows) {
            "a Windows PE/DLL file"
        } else {
            "an ELF shared library"
        },
        std::env::consts::ARCH,
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

fn host_architecture() -> Option<Architecture> {
    match std::env::consts::ARCH {
        "x86_64" => Some(Architecture::X86_64),
        "x86" => Some(Architecture::I386),
        "aarch64" => Some(Architecture::Aarch64),
        "arm" => Some(Architecture::Arm),
        "riscv64" => Some(Architecture::Riscv64),
        _ => None,
    }
}

fn architecture_name(a: Architecture) -> String {
    match a {
        Architecture::X86_64 => "x86_64".into(),
        Architecture::X86_64_X32 => "x86_64 (x32 ABI)".into(),
        Architecture::I386 => "x86 (32-bit)".into(),
        Architecture::Aarch64 => "aarch64".into(),
        Architecture::Arm => "arm (32-bit)".into(),
        Architecture::Riscv64 => "riscv64".into(),
        other => format!("{other:?}").to_lowercase(),
    }
}

/// Checks that `data` is a shared library this process can load and that it exports every
/// function in `required` ([`REQUIRED_FUNCTIONS`] or [`REQUIRED_FUNCTIONS_3`]).
pub fn check(data: &[u8], required: &[&'static str]) -> Result<(), LibraryProblem> {
    let wrong = |found: String| LibraryProblem::WrongKind {
        found,
        expected: expected_kind(),
    };
    let kind = match FileKind::parse(data) {
        Ok(k) => k,
        Err(_) => {
            return Err(wrong(if data.is_empty() {
                "an empty file, not a shared library".into()
            } else if data.starts_with(b"#!") || data.iter().take(512).all(|b| b.is_ascii()) {
                "a text file, not a shared library".into()
            } else {
                "not a shared library (neither ELF, PE nor Mach-O)".into()
            }))
        }
    };
    let file = match object::File::parse(data) {
        Ok(f) => f,
        Err(e) => {
            return Err(wrong(match kind {
                FileKind::Elf32 | FileKind::Elf64 => format!("a damaged ELF file ({e})"),
                other => format!("a damaged {other:?} file ({e})"),
            }))
        }
    };
    let arch = architecture_name(file.architecture());
    let bits = if file.is_64() { "64-bit" } else { "32-bit" };
    match file.format() {
        // The host's own format: ELF, or PE on Windows.
        BinaryFormat::Elf if !cfg!(windows) => {}
        BinaryFormat::Pe if cfg!(windows) => {}
        BinaryFormat::Elf => {
            return Err(wrong(format!(
                "an ELF file for {arch} ({bits}), not a Windows PE/DLL file"
            )))
        }
        BinaryFormat::Pe | BinaryFormat::Coff => {
            return Err(wrong(format!(
                "a Windows PE/DLL file for {arch} ({bits}), not an ELF shared library"
            )))
        }
        BinaryFormat::MachO => {
            return Err(wrong(format!(
                "a macOS Mach-O file for {arch} ({bits}), not an ELF shared library"
            )))
        }
        other => {
            return Err(wrong(format!(
                "a {other:?} file, not an ELF shared library"
            )))
        }
    }
    if host_architecture().is_some_and(|host| host != file.architecture())
        || (std::env::consts::ARCH == "x86_64" && !file.is_64())
    {
        let what = if file.kind() == ObjectKind::Dynamic {
            "shared library"
        } else {
            "file"
        };
        return Err(wrong(format!("an ELF {what} for {arch} ({bits})")));
    }
    if file.kind() != ObjectKind::Dynamic {
        let what = match file.kind() {
            ObjectKind::Executable => "an executable",
            ObjectKind::Relocatable => "a relocatable object (.o)",
            ObjectKind::Core => "a core dump",
            _ => "an ELF file of unknown type",
        };
        return Err(wrong(format!("{what} for {arch}, not a shared library")));
    }
    let exports = file.exports().map_err(|e| {
        wrong(format!(
            "an ELF shared library whose symbol table cannot be read ({e})"
        ))
    })?;
    let missing: Vec<&'static str> = required
        .iter()
        .copied()
        .filter(|f| !exports.iter().any(|e| e.name() == f.as_bytes()))
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(LibraryProblem::MissingFunctions(missing))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_libraries_are_named() {
        let text = |p| match p {
            Err(LibraryProblem::WrongKind { found, .. }) => found,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            text(check(b"", &REQUIRED_FUNCTIONS)),
            "an empty file, not a shared library"
        );
        assert_eq!(
            text(check(b"hello, world\n", &REQUIRED_FUNCTIONS)),
            "a text file, not a shared library"
        );
        assert!(text(check(
            &[0xff, 0x00, 0x13, 0x37, 0x00, 0x80],
            &REQUIRED_FUNCTIONS
        ))
        .contains("neither ELF"));
    }
}
