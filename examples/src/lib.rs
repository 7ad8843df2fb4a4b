//! The papers' experiments as bundled systems (`examples/<name>/`), run on the co-simulation
//! engine ([`spurio_master`]), each writing a report: a Markdown table with the paper's figure
//! beside ours, and the plots the papers show. `spurio-experiments` (this crate's command, behind
//! `scripts/experiments`) runs them all and writes `REPORT.md` in the output folder.
//!
//! Each experiment is a module with one `run(&ExperimentContext) -> Result<Report>` that reads
//! as scenario → runs → scores → report: it loads its systems from `examples/<name>/*.toml`
//! (so a user can run them with `spurio run` too), edits them by name and runs them per seed
//! ([`runner`], one thread pool for all), scores the runs and fills a [`Report`]. The analysis
//! they share with the command line comes from `spurio-analysis`: the outlier
//! [`diagnostics`] (and [`diagnose`], behind `spurio diagnose`) and the [`plot`]s.

#![forbid(unsafe_code)]

pub use spurio_analysis::{diagnose, diagnostics, plot};

pub mod cosine_outliers;
pub mod crane_adaptive;
pub mod crane_free_swing;
pub mod crane_identification;
pub mod distributed_observer;
pub mod fmu_identification;
pub mod generator_identification;
pub mod opamp_identification;
pub mod real_data;
pub mod runner;

use anyhow::{Context as _, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where an experiment finds its inputs and writes its outputs.
#[derive(Debug, Clone)]
pub struct ExperimentContext {
    /// The repository root (holding `examples/` and `build/fmus/`).
    pub repo: PathBuf,
    /// This experiment's output folder (created before `run`).
    pub out_dir: PathBuf,
    /// Monte-Carlo runs where the paper reports mean ± std (100 by default).
    pub seeds: usize,
    /// The worker threads every Monte-Carlo study of the run shares.
    pub pool: Arc<rayon::ThreadPool>,
}

impl ExperimentContext {
    /// `examples/<experiment>/<file>`.
    pub fn example(&self, experiment: &str, file: &str) -> PathBuf {
        self.repo.join("examples").join(experiment).join(file)
    }

    /// Loads and resolves `examples/<experiment>/<file>` (FMU paths relative to that file).
    pub fn system(&self, experiment: &str, file: &str) -> Result<spurio_master::System> {
        let path = self.example(experiment, file);
        spurio_master::System::from_file(&path)
            .with_context(|| format!("loading {}", path.display()))
    }
}

/// One line of a report's table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What is measured.
    pub quantity: String,
    /// The paper's figure (or the independent reference of docs/experiments.md §4), as printed.
    pub paper: String,
    /// Ours.
    pub ours: String,
    /// The goal ("≤ 0.0124"), empty if none.
    pub goal: String,
    /// Whether the goal is met (None: no goal).
    pub met: Option<bool>,
}

impl Row {
    /// A row without a goal.
    pub fn info(quantity: &str, paper: impl Into<String>, ours: impl Into<String>) -> Self {
        Self {
            quantity: quantity.to_string(),
            paper: paper.into(),
            ours: ours.into(),
            goal: String::new(),
            met: None,
        }
    }

    /// A row with a goal and whether it is met.
    pub fn goal(
        quantity: &str,
        paper: impl Into<String>,
        ours: impl Into<String>,
        goal: &str,
        met: bool,
    ) -> Self {
        Self {
            quantity: quantity.to_string(),
            paper: paper.into(),
            ours: ours.into(),
            goal: goal.to_string(),
            met: Some(met),
        }
    }
}

/// What an experiment found.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Title (the paper and section).
    pub title: String,
    /// A paragraph: the setup, in words.
    pub setup: String,
    /// The table: paper beside ours.
    pub rows: Vec<Row>,
    /// Figures written into the experiment's output folder (file names), with captions.
    pub figures: Vec<(String, String)>,
    /// Remarks: methods chosen, differences from the paper.
    pub notes: Vec<String>,
    /// Named figures for tests: (key, value) — the numbers the integration tests pin.
    pub figures_of_merit: Vec<(String, f64)>,
}

impl Report {
    /// The figure of merit called `key`.
    pub fn value(&self, key: &str) -> Option<f64> {
        self.figures_of_merit
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| *v)
    }

    /// Whether every goal is met.
    pub fn all_goals_met(&self) -> bool {
        self.rows.iter().all(|r| r.met != Some(false))
    }

    /// The report as Markdown (figures linked relative to `prefix`).
    pub fn to_markdown(&self, prefix: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "## {}\n", self.title);
        if !self.setup.is_empty() {
            let _ = writeln!(s, "{}\n", self.setup);
        }
        let _ = writeln!(
            s,
            "| quantity | paper | ours | goal | met |\n|---|---|---|---|---|"
        );
        for r in &self.rows {
            let met = match r.met {
                Some(true) => "yes",
                Some(false) => "**no**",
                None => "",
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {met} |",
                r.quantity, r.paper, r.ours, r.goal
            );
        }
        for (file, caption) in &self.figures {
            let _ = writeln!(s, "\n![{caption}]({prefix}{file})\n\n*{caption}*");
        }
        if !self.notes.is_empty() {
            let _ = writeln!(s);
            for n in &self.notes {
                let _ = writeln!(s, "- {n}");
            }
        }
        s
    }
}

/// One bundled experiment.
pub struct Experiment {
    /// Folder name under `examples/` and under the output folder.
    pub name: &'static str,
    /// One line.
    pub description: &'static str,
    /// Runs it.
    pub run: fn(&ExperimentContext) -> Result<Report>,
}

/// Every bundled experiment, in report order.
pub fn all() -> Vec<Experiment> {
    vec![Experiment {
        name: "crane_free_swing",
        description: "free swing of the nonlinear crane against the linearised period",
        run: crane_free_swing::run,
    },
    Experiment {
        name: "generator_identification",
        description: "wind generator identified by DKF and DKF-rsKF under outliers (paper 001 §5)",
        run: generator_identification::run,
    },
    Experiment {
        name: "distributed_observer",
        description: "two-agent distributed observer against the centralised Kalman filter (paper 004 §5)",
        run: distributed_observer::run,
    },
    Experiment {
        name: "crane_adaptive",
        description: "adaptive pole placement of the crane with 5 % outliers: DKF alone vs DKF-rsKF (paper 000 §VII-B)",
        run: crane_adaptive::run,
    },
    Experiment {
        name: "crane_identification",
        description: "cart mass, rod length and friction of the GantryCrane ME FMU from a recorded closed-loop run with 20 dB noise and 5 % outliers, offline and online",
        run: crane_identification::run,
    },
    Experiment {
        name: "fmu_identification",
        description: "the Reference FMUs' VanDerPol mu, BouncingBall e and Dahlquist k from their own outputs with noise and 5 % outliers, offline and online, and the Nile local level by maximum likelihood (Durbin & Koopman)",
        run: fmu_identification::run,
    },
    Experiment {
        name: "cosine_outliers",
        description: "noisy cosine with outliers: sKF vs rsKF, E_res, moments, Grubbs (papers 000, 001)",
        run: cosine_outliers::run,
    },
    Experiment {
        name: "opamp_identification",
        description: "op-amp filter identified from a noisy step and a PRBS: RLS with Steiglitz–McBride iterations (paper 002)",
        run: opamp_identification::run,
    },
    Experiment {
        name: "real_data",
        description: "the DaISy hair dryer (measured data): RLS, DKF and the robust paths through the data source, with outliers and missing samples",
        run: real_data::run,
    }]
}

/// Runs the named experiments (all if `only` is empty) into `out_dir/<name>/`, writes
/// `out_dir/REPORT.md`, and returns the reports.
pub fn run_all(
    repo: &Path,
    out_dir: &Path,
    only: &[String],
    seeds: usize,
    threads: usize,
) -> Result<Vec<(String, Report)>> {
    let experiments = all();
    for name in only {
        if !experiments.iter().any(|e| e.name == name) {
            let known: Vec<&str> = experiments.iter().map(|e| e.name).collect();
            anyhow::bail!("unknown experiment `{name}` (known: {})", known.join(", "));
        }
    }
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .context("thread pool")?,
    );
    let mut reports = Vec::new();
    let mut text = String::from("# spurio: the papers' experiments\n\nEach section puts the paper's figure beside ours; `met` says whether our goal (docs/experiments.md §4) holds.\n\n");
    for e in experiments
        .iter()
        .filter(|e| only.is_empty() || only.iter().any(|n| n == e.name))
    {
        let dir = out_dir.join(e.name);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let ctx = ExperimentContext {
            repo: repo.to_path_buf(),
            out_dir: dir.clone(),
            seeds,
            pool: pool.clone(),
        };
        let started = std::time::Instant::now();
        let report = (e.run)(&ctx).with_context(|| format!("experiment {}", e.name))?;
        eprintln!(
            "{}: done in {:.1} s",
            e.name,
            started.elapsed().as_secs_f64()
        );
        std::fs::write(dir.join("report.md"), report.to_markdown(""))?;
        text.push_str(&report.to_markdown(&format!("{}/", e.name)));
        text.push('\n');
        reports.push((e.name.to_string(), report));
    }
    std::fs::write(out_dir.join("REPORT.md"), text)?;
    Ok(reports)
}
