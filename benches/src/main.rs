//! `scripts/bench`: one command that prints, in one run, our FMUs' cost per step against the
//! arithmetic floor, and `spurio run` side by side with OMSimulator and the FMU Compliance
//! Checker on the Reference FMUs, with ratios. Measurements of one table alternate (A, B,
//! A, B …) so that a drift of the machine hits every subject alike; figures are medians.
//! Speed is measured here, never asserted: `--quick` is the seconds-long smoke run
//! `scripts/test` makes.

#![forbid(unsafe_code)]

mod baseline;
mod fmus;
mod stats;
mod tools;

use anyhow::{Context, Result};
use clap::Parser;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use tools::{per_step, system_file, Runner, ThirdParty, STEP};

#[derive(Parser)]
#[command(about = "Per-step costs of our FMUs and of spurio run beside OMSimulator and fmuCheck")]
struct Args {
    /// A seconds-long smoke run (tiny counts, one round): checks that every part runs.
    #[arg(long)]
    quick: bool,
    /// Also count instructions per step of our FMUs with callgrind (valgrind).
    #[arg(long)]
    instructions: bool,
    /// The `spurio` binary to time (default: target/release/spurio).
    #[arg(long)]
    spurio: Option<PathBuf>,
    /// The packaged FMUs (default: build/fmus).
    #[arg(long)]
    fmus: Option<PathBuf>,
    /// Before and after: time the FMUs of DIR (an earlier build, e.g. from `scripts/bench
    /// --baseline-rev REV`) against today's, interleaved, through the C driver; prints only
    /// that table.
    #[arg(long, value_name = "DIR")]
    baseline: Option<PathBuf>,
    /// What the baseline is, for the table's heading (e.g. the revision it was built from).
    #[arg(long, requires = "baseline")]
    baseline_label: Option<String>,
    /// Internal (what callgrind runs): step this row's FMU `--steps` times and exit.
    #[arg(long, hide = true, requires = "steps")]
    count: Option<String>,
    #[arg(long, hide = true)]
    steps: Option<u64>,
}

/// Nanoseconds as text: ns below 10 µs, µs above.
fn ns(v: f64) -> String {
    if !v.is_finite() {
        "—".into()
    } else if v >= 10_000.0 {
        format!("{:.1} µs", v / 1000.0)
    } else if v >= 100.0 {
        format!("{v:.0} ns")
    } else {
        format!("{v:.1} ns")
    }
}

fn optional(v: Option<f64>, show: impl Fn(f64) -> String) -> String {
    v.map_or_else(|| "—".into(), show)
}

fn main() -> Result<()> {
    let args = Args::parse();
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let fmus = args.fmus.clone().unwrap_or_else(|| repo.join("build/fmus"));
    spurio_master::logging::install(false);
    if let (Some(fmu), Some(steps)) = (&args.count, args.steps) {
        return fmus::count_run(&fmus, fmu, steps);
    }
    let spurio = args
        .spurio
        .clone()
        .unwrap_or_else(|| repo.join("target/release/spurio"));
    if args.quick {
        println!("(--quick: a smoke run with tiny counts; its figures measure nothing)\n");
    }
    if let Some(dir) = &args.baseline {
        return before_and_after(&args, &repo, dir, &fmus);
    }
    our_fmus(&args, &repo, &fmus)?;
    match ThirdParty::find(&repo) {
        Some(third) => side_by_side(&args, &spurio, &third)?,
        None => println!(
            "\n(no tests/third_party/reference-fmus, nor a SPURIO_THIRD_PARTY folder with them: \
             OMSimulator, fmuCheck and the Reference FMUs are needed for the side-by-side tables)"
        ),
    }
    Ok(())
}

/// The table of our FMUs.
fn our_fmus(args: &Args, repo: &Path, fmus: &Path) -> Result<()> {
    let (rounds, batch_ms) = if args.quick { (3, 0.2) } else { (101, 2.0) };
    let measured = fmus::measure(repo, fmus, rounds, batch_ms)?;
    println!(
        "## Our FMUs, per step through the C ABI (fmi2SetReal of every input + fmi2DoStep + \
         fmi2Get* of every output), median of {rounds} interleaved batches (the two paths \
         alternate)\n"
    );
    println!(
        "| FMU | outputs read | direct C ABI | through spurio's importer | instructions \
         (importer path) | floor | direct / floor | target | met |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (row, m) in fmus::ROWS.iter().zip(&measured) {
        let instructions = if args.instructions {
            let (short, long) = if args.quick { (5, 25) } else { (100, 600) };
            Some(fmus::instructions(fmus, row.fmu, short, long).with_context(|| row.label)?)
        } else {
            None
        };
        let time_met = row.target_ns.map(|t| m.direct_ns <= t);
        let instructions_met = row
            .target_instructions
            .zip(instructions)
            .map(|(t, i)| i <= t);
        let met = match (time_met, instructions_met) {
            (None, None) => "—",
            (a, b) if a.unwrap_or(true) && b.unwrap_or(true) => "yes",
            _ => "no",
        };
        let target = match (row.target_ns, row.target_instructions) {
            (Some(t), Some(i)) => format!("≤ {}, ≤ {}k instr.", ns(t), i / 1000.0),
            (Some(t), None) => format!("≤ {}", ns(t)),
            _ => "—".into(),
        };
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {target} | {met} |",
            row.label,
            m.outputs_read,
            ns(m.direct_ns),
            ns(m.importer_ns),
            optional(instructions, |i| format!("{:.0}", i)),
            optional(row.floor_ns, ns),
            optional(row.floor_ns, |f| format!("{:.1}×", m.direct_ns / f)),
        );
    }
    println!(
        "\nFloors and targets are the estimates in benches/src/fmus.rs (AMD Zen 4): DkfRsKfGenerator ≈ 8.1 kflop \
         (0.2 µs with AVX2+FMA), LinearSystem three Gaussian draws (≈ 85 ns), the scalar filters \
         ≈ 25 flops (≈ 10 ns); WindGenerator's target is 10× its 120 µs then; none is given for \
         AdaptiveStateFeedback and GantryCrane.\n\
         The target is judged on the direct column: it is set per FMU through the C ABI \
         (set inputs + fmi2DoStep + get outputs), which the C driver (tests/allocations/driver.c, \
         gcc -O2) measures with nothing between its loop and the FMU's functions; the importer's \
         column adds what spurio's master pays per call (its Instance over rust-fmi's wrappers), \
         a cost of the master, measured per instance-step below. Both paths use the same \
         precomputed inputs (1024 steps cycled). The instructions (callgrind) count the importer \
         path, whole steps of this benchmark's own loop."
    );
    Ok(())
}

/// The table of `--baseline DIR`: DIR's FMUs against today's, with (`--instructions`) the
/// instructions per step of each build on the same C driver loop.
fn before_and_after(args: &Args, repo: &Path, dir: &Path, fmus: &Path) -> Result<()> {
    anyhow::ensure!(
        dir.is_dir(),
        "--baseline {}: no such directory",
        dir.display()
    );
    let (rounds, batch_ms) = if args.quick { (3, 0.2) } else { (101, 2.0) };
    let label = args
        .baseline_label
        .clone()
        .unwrap_or_else(|| dir.display().to_string());
    let instructions = args
        .instructions
        .then_some(if args.quick { (5, 25) } else { (100, 600) });
    let (compared, left_out) =
        baseline::compare(repo, dir, fmus, (rounds, batch_ms), instructions)?;
    println!(
        "## Before and after, per step straight through the C ABI (tests/allocations/driver.c \
         --time, the same driver for both: fmi2SetReal of every input + fmi2DoStep + the \
         getters of every output), median of {rounds} interleaved batches; speed-up = the \
         median of the rounds' baseline / now\n"
    );
    print!("{}", baseline::table(&label, &compared, &left_out));
    if args.instructions {
        println!(
            "\nInstructions per step: callgrind on the same driver loop as the timing (two run \
             lengths, so loading and initialisation cancel; the loop's own few instructions a \
             step included)."
        );
    }
    Ok(())
}

/// `spurio run` against OMSimulator and the FMU Compliance Checker, and the master's
/// overhead per instance-step.
fn side_by_side(args: &Args, spurio: &Path, third: &ThirdParty) -> Result<()> {
    anyhow::ensure!(
        spurio.is_file(),
        "{} is missing: cargo build --release -p spurio-cli",
        spurio.display()
    );
    let scale = if args.quick { 1000 } else { 1 };
    let rounds = if args.quick { 1 } else { 5 };
    let dir = tempfile::tempdir()?;
    let d = dir.path().to_path_buf();
    let vdp = third.reference("VanDerPol");
    let feedthrough = third.reference("Feedthrough");
    let pair_instances = [
        ("vdp".to_string(), vdp.clone()),
        ("ft".to_string(), feedthrough.clone()),
    ];
    let pair_connections = ["vdp.x0 -> ft.Float64_continuous_input".to_string()];
    let alone = [("vdp".to_string(), vdp.clone())];
    let (chain_instances, chain_connections) = tools::chain(third, 8);
    let lengths = [
        (200_000 / scale, 1_000_000 / scale),
        (20_000 / scale, 200_000 / scale),
        (1_000_000 / scale, 10_000_000 / scale),
        (100_000 / scale, 1_000_000 / scale),
    ];
    for &(short, long) in &lengths {
        for steps in [short, long] {
            system_file(
                &d,
                "pair",
                steps,
                "gauss-seidel",
                &pair_connections,
                &pair_instances,
            )?;
            system_file(&d, "alone", steps, "gauss-seidel", &[], &alone)?;
            system_file(
                &d,
                "chain",
                steps,
                "jacobi",
                &chain_connections,
                &chain_instances,
            )?;
        }
    }
    // OMSimulator runs the same system exported as SSP; the stop time is its argument.
    let ssp = d.join("pair.ssp");
    let export = std::process::Command::new(spurio)
        .arg("ssp-export")
        .arg(d.join(format!("pair_{}.toml", lengths[0].1)))
        .arg(&ssp)
        .output()?;
    anyhow::ensure!(
        export.status.success(),
        "spurio ssp-export failed: {}",
        String::from_utf8_lossy(&export.stderr)
    );

    let run = |name: &'static str, extra: Vec<OsString>| {
        let d = d.clone();
        move |steps: u64| {
            let mut a: Vec<OsString> =
                vec!["run".into(), d.join(format!("{name}_{steps}.toml")).into()];
            a.extend(extra.iter().cloned());
            a
        }
    };
    let no_record = || vec![OsString::from("--no-record")];
    let csv_out = |file: &str| vec![OsString::from("--out"), d.join(file).into()];
    for (short, long) in &lengths[..2] {
        for steps in [*short, *long] {
            tools::oms_script(&d, &ssp, "pair", steps, "")?;
            tools::oms_script(&d, &ssp, "pair", steps, "oms.csv")?;
        }
    }
    let oms = |tag: &'static str| {
        let d = d.clone();
        move |steps: u64| vec![OsString::from(d.join(format!("oms_{tag}_{steps}.lua")))]
    };

    println!(
        "\n## spurio run beside the other tools (Reference FMUs, step 2⁻¹⁰ s), time per step \
         from two run lengths (start-up cancels), median of {rounds} interleaved rounds\n"
    );
    println!("| system | spurio | peer | peer / spurio | target |");
    println!("|---|---|---|---|---|");
    let omsimulator = third.omsimulator();
    if omsimulator.is_file() {
        for (case, (short, long), ours, theirs, target) in [
            (
                "VanDerPol → Feedthrough, no output; peer OMSimulator",
                lengths[0],
                Runner::new("spurio run --no-record", spurio, run("pair", no_record())),
                Runner::new("OMSimulator", &omsimulator, oms("none")).in_dir(&d),
                4.0,
            ),
            (
                "VanDerPol → Feedthrough, a CSV every step; peer OMSimulator",
                lengths[1],
                Runner::new("spurio run", spurio, run("pair", csv_out("spurio.csv"))),
                Runner::new("OMSimulator", &omsimulator, oms("csv")).in_dir(&d),
                8.0,
            ),
        ] {
            let t = per_step(&mut [ours, theirs], short, long, rounds)?;
            println!(
                "| {case} | {} | {} | {:.1}× | ≥ {target}× ({}) |",
                ns(t[0]),
                ns(t[1]),
                t[1] / t[0],
                if t[1] / t[0] >= target {
                    "met"
                } else {
                    "not met"
                }
            );
        }
    } else {
        println!("| VanDerPol → Feedthrough | — | OMSimulator not found | — | — |");
    }
    let fmu_check = third.fmu_check();
    if fmu_check.is_file() {
        let unpack = d.join("fmucheck");
        std::fs::create_dir_all(&unpack)?;
        let vdp_arg = vdp.clone();
        let check = move |steps: u64| -> Vec<OsString> {
            let mut a: Vec<OsString> = ["-k", "cs", "-n", "1", "-l", "1", "-o", "/dev/null"]
                .map(OsString::from)
                .to_vec();
            a.extend([
                "-h".into(),
                format!("{STEP:?}").into(),
                "-s".into(),
                format!("{:?}", steps as f64 * STEP).into(),
                "-z".into(),
                unpack.clone().into(),
                vdp_arg.clone().into(),
            ]);
            a
        };
        let (short, long) = lengths[2];
        let t = per_step(
            &mut [
                Runner::new("spurio run --no-record", spurio, run("alone", no_record())),
                Runner::new("fmuCheck", &fmu_check, check),
            ],
            short,
            long,
            rounds,
        )?;
        println!(
            "| VanDerPol alone, recording off; peer the FMU Compliance Checker's loop (-n 1) | {} | {} | {:.2}× | spurio ≤ 2× the peer ({}) |",
            ns(t[0]),
            ns(t[1]),
            t[1] / t[0],
            if t[0] <= 2.0 * t[1] { "met" } else { "not met" }
        );
    } else {
        println!("| VanDerPol alone | — | fmuCheck not found | — | — |");
    }

    // The master's own cost: the chain in spurio run, minus the same FMI calls made bare.
    let (short, long) = lengths[3];
    let through_master = per_step(
        &mut [Runner::new(
            "spurio run --no-record",
            spurio,
            run("chain", no_record()),
        )],
        short,
        long,
        rounds,
    )?[0]
        / 8.0;
    let bare = tools::bare_chain(third, 8, long / 10, if args.quick { 1 } else { 9 })?;
    println!(
        "\n## Master overhead per instance-step, recording off (VanDerPol → 7 Feedthrough, Jacobi)\n"
    );
    println!("| spurio run --no-record | the same FMI calls made directly | overhead | target |");
    println!("|---|---|---|---|");
    println!(
        "| {} | {} | {} | ≤ 60 ns ({}) |",
        ns(through_master),
        ns(bare),
        ns(through_master - bare),
        if through_master - bare <= 60.0 {
            "met"
        } else {
            "not met"
        }
    );
    Ok(())
}
