//! The hair-dryer record and SLICOT's model of it, as `scripts/setup` fetches them from
//! Debian's `libslicot-doc` into `data/slicot/` (GPL-2+, never committed): `IB01BD.dat.gz`
//! (three header lines, then the 1000 inputs u, then the 1000 outputs y) and `IB01BD.res`
//! (the order-4 innovation model SLICOT's IB01BD example identifies from the whole record).
//! Also what the experiment does to the record: the contamination by outliers (the Sensor
//! model of docs/models.md §2.6) and the removal of samples, and the data CSV the master reads.

use super::models::InnovationModel;
use anyhow::{anyhow, bail, Context as _, Result};
use nalgebra::{DMatrix, DVector};
use spurio::signals::rng::RandomGenerator;
use spurio::signals::sensor::{NoiseLevel, OutlierParameters, Sensor, SensorParameters};
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// Samples in the record.
pub const SAMPLES: usize = 1000;
/// Its sampling period [s].
pub const TS: f64 = 0.08;
/// The folder `scripts/setup` fetches into, relative to the repository.
pub const FOLDER: &str = "data/slicot";

/// The path of `file` in the fetched folder, or an error telling to run `scripts/setup`.
fn fetched(repo: &Path, file: &str) -> Result<PathBuf> {
    let path = repo.join(FOLDER).join(file);
    if !path.is_file() {
        bail!(
            "the hair-dryer record {} is not there: run scripts/setup (it fetches Debian's \
             libslicot-doc, GPL-2+, into {FOLDER}/)",
            path.display()
        );
    }
    Ok(path)
}

/// The recorded input (heater voltage) and output (thermocouple voltage) [V].
#[derive(Debug, Clone)]
pub struct Record {
    pub u: Vec<f64>,
    pub y: Vec<f64>,
}

impl Record {
    /// Reads `data/slicot/IB01BD.dat.gz`, checking its layout: the header's sample count (the
    /// fifth field of line 2, NSMP) is 1000 with one input and one output, and 2000 values
    /// follow.
    pub fn load(repo: &Path) -> Result<Self> {
        let path = fetched(repo, "IB01BD.dat.gz")?;
        let mut text = String::new();
        flate2::read::GzDecoder::new(
            std::fs::File::open(&path).with_context(|| format!("opening {}", path.display()))?,
        )
        .read_to_string(&mut text)
        .with_context(|| format!("decompressing {}", path.display()))?;
        let lines: Vec<&str> = text.lines().collect();
        let header: Vec<&str> = lines
            .get(1)
            .map(|l| l.split_whitespace().collect())
            .unwrap_or_default();
        // NOBR N M L NSMP RCOND TOL.
        if header.len() < 5 || header[2] != "1" || header[3] != "1" || header[4] != "1000" {
            bail!(
                "{}, line 2: expected `NOBR N M=1 L=1 NSMP=1000 …`, found `{}`",
                path.display(),
                lines.get(1).unwrap_or(&"")
            );
        }
        let mut values = Vec::with_capacity(2 * SAMPLES);
        for (i, line) in lines.iter().enumerate().skip(3) {
            for cell in line.split_whitespace() {
                values.push(cell.parse::<f64>().map_err(|_| {
                    anyhow!(
                        "{}, line {}: `{cell}` is not a number",
                        path.display(),
                        i + 1
                    )
                })?);
            }
        }
        if values.len() != 2 * SAMPLES {
            bail!(
                "{}: {} values after the header, expected {} (u then y)",
                path.display(),
                values.len(),
                2 * SAMPLES
            );
        }
        let y = values.split_off(SAMPLES);
        Ok(Self { u: values, y })
    }
}

/// `v` minus its mean, and the mean.
pub fn centred(v: &[f64]) -> (Vec<f64>, f64) {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| x - mean).collect(), mean)
}

/// The standard deviation of `v` (population).
pub fn deviation(v: &[f64]) -> f64 {
    let (c, _) = centred(v);
    (c.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// The numbers of the block that follows the line containing `title` in SLICOT's result file,
/// up to the next blank line, as rows.
fn block(text: &str, title: &str, file: &Path) -> Result<Vec<Vec<f64>>> {
    let mut lines = text.lines().skip_while(|l| !l.contains(title));
    if lines.next().is_none() {
        bail!("{}: no `{title}`", file.display());
    }
    lines
        .take_while(|l| !l.trim().is_empty())
        .map(|l| {
            l.split_whitespace()
                .map(|c| {
                    c.parse::<f64>().map_err(|_| {
                        anyhow!("{}, `{title}`: `{c}` is not a number", file.display())
                    })
                })
                .collect()
        })
        .collect()
}

/// SLICOT's order-4 model of the record (`IB01BD.res`: A, B, C, D and the Kalman gain K,
/// printed to four decimals).
pub fn slicot_model(repo: &Path) -> Result<InnovationModel> {
    let path = fetched(repo, "IB01BD.res")?;
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let a = block(&text, "state matrix A", &path)?;
    let n = a.len();
    let column = |title: &str| -> Result<DVector<f64>> {
        let rows = block(&text, title, &path)?;
        let v: Vec<f64> = rows.into_iter().flatten().collect();
        if v.len() != n {
            bail!(
                "{}: `{title}` has {} entries, A is {n}×{n}",
                path.display(),
                v.len()
            );
        }
        Ok(DVector::from_vec(v))
    };
    if n == 0 || a.iter().any(|r| r.len() != n) {
        bail!("{}: the state matrix A is not square", path.display());
    }
    let d = block(&text, "input-output matrix D", &path)?;
    let d = match d.as_slice() {
        [row] if row.len() == 1 => row[0],
        _ => bail!("{}: D is not 1×1", path.display()),
    };
    Ok(InnovationModel {
        a: DMatrix::from_fn(n, n, |i, j| a[i][j]),
        b: column("input matrix B")?,
        c: column("output matrix C")?,
        d,
        k: column("Kalman gain matrix K")?,
    })
}

/// The record's output with ε-contaminated outliers: the Sensor FMU's model (docs/models.md
/// §2.6) without noise, ε = 0.05, magnitudes U(0, `max_magnitude`) with a random sign, seeded
/// (`spurio::signals::sensor`, the same streams as the FMU's). Returns the contaminated output
/// and which samples carry an outlier.
pub fn contaminated(y: &[f64], max_magnitude: f64, seed: u64) -> Result<(Vec<f64>, Vec<bool>)> {
    let mut sensor = Sensor::new(SensorParameters {
        noise: NoiseLevel::Variance(0.0),
        outliers: OutlierParameters {
            epsilon: 0.05,
            min_magnitude: 0.0,
            max_magnitude,
            window_start: 0.0,
            window_end: f64::INFINITY,
        },
        quantiser: None,
        seed,
    })?;
    let readings: Vec<_> = y
        .iter()
        .enumerate()
        .map(|(k, &v)| sensor.measure(k as f64 * TS, v))
        .collect();
    Ok((
        readings.iter().map(|r| r.measured).collect(),
        readings.iter().map(|r| r.outlier).collect(),
    ))
}

/// Which samples are missing: `fraction` of each half of the record, drawn without
/// replacement (a partial Fisher–Yates shuffle on the seeded xoshiro256** stream).
pub fn missing(samples: usize, fraction: f64, seed: u64) -> Vec<bool> {
    let mut gone = vec![false; samples];
    let mut rng = RandomGenerator::for_stream(seed, 2);
    let half = samples / 2;
    for (start, len) in [(0, half), (half, samples - half)] {
        let mut order: Vec<usize> = (start..start + len).collect();
        let count = (fraction * len as f64).round() as usize;
        for i in 0..count {
            let j = i + (rng.uniform() * (len - i) as f64) as usize;
            order.swap(i, j.min(len - 1));
            gone[order[i]] = true;
        }
    }
    gone
}

/// Writes the data CSV the master reads (`time`, `u`, `u_delayed` = u(k−2), `u_delayed_more`
/// = u(k−3), `y`, `y_previous` = y(k−1); the inputs are 0 before the record starts, a missing
/// output an empty cell, as is `y_previous` at the first sample).
pub fn write_csv(path: &Path, u: &[f64], y: &[f64], gone: &[bool]) -> Result<()> {
    use std::fmt::Write as _;
    let mut text = String::from(
        "\"time [s]\",\"u [V]\",\"u_delayed [V]\",\"u_delayed_more [V]\",\"y [V]\",\"y_previous [V]\",\"y_previous2 [V]\"\n",
    );
    let cell = |k: Option<usize>| match k {
        Some(k) if !gone[k] => format!("{:.17e}", y[k]),
        _ => String::new(),
    };
    let lagged = |k: usize, lag: usize| if k >= lag { u[k - lag] } else { 0.0 };
    for (k, uk) in u.iter().enumerate().take(y.len()) {
        let _ = writeln!(
            text,
            "{},{:.17e},{:.17e},{:.17e},{},{},{}",
            k as f64 * TS,
            uk,
            lagged(k, 2),
            lagged(k, 3),
            cell(Some(k)),
            cell(k.checked_sub(1)),
            cell(k.checked_sub(2))
        );
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tenth_of_each_half_goes_missing_and_the_draw_is_seeded() {
        let a = missing(1000, 0.1, 1);
        assert_eq!(a[..500].iter().filter(|g| **g).count(), 50);
        assert_eq!(a[500..].iter().filter(|g| **g).count(), 50);
        assert_eq!(a, missing(1000, 0.1, 1));
        assert_ne!(a, missing(1000, 0.1, 2));
    }

    #[test]
    fn outliers_hit_about_one_sample_in_twenty_within_the_magnitude() {
        let y = vec![1.0; 4000];
        let (c, flags) = contaminated(&y, 2.0, 3).unwrap();
        let hits = flags.iter().filter(|f| **f).count();
        assert!((150..=250).contains(&hits), "{hits}");
        for (v, f) in c.iter().zip(&flags) {
            assert!(if *f {
                (v - 1.0).abs() <= 2.0
            } else {
                *v == 1.0
            });
        }
    }
}
