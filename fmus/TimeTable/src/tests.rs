use super::*;
use spurio_export::harness::Harness;
use spurio_export::types::Status;

/// The value references of column j's outputs.
fn vr(j: usize, reading: Reading) -> u32 {
    (Reading::ALL.len() * j + reading as usize) as u32
}

/// What the master's data source reads of column j at time t (hold or linear).
fn master_reads(table: &DataTable, j: usize, reading: Reading, t: f64) -> f64 {
    let mut cursor = Cursor::default();
    table.seek(&mut cursor, t);
    table.reading(cursor, j, reading, t)
}

/// A packaged table in a temporary `resources/` folder: its configuration and the folder.
fn packaged(text: &str, interpolation: Interpolation) -> (Config, PathBuf) {
    let dir = std::env::temp_dir().join(format!(
        "spurio-time-table-{}-{}",
        std::process::id(),
        text.len() * 2 + interpolation.code() as usize
    ));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("rig.csv"), text).unwrap();
    let table = DataTable::parse(text, &dir.join("rig.csv"), interpolation).unwrap();
    let mut config = Config::new();
    for (key, value) in Declaration::of(&table, "rig.csv").unwrap().entries() {
        config.set(&key, value);
    }
    (config, dir)
}

const RIG: &str =
    "time,force [N],x\n0,0.1,1\n0.1,0.7,\n0.2,-2.5,3\n0.30000000000000004,nan,4\n0.4,1e-3,5\n";

#[test]
fn the_bundled_table_reads_as_the_master_reads_it_at_and_between_samples() {
    let table = example(Interpolation::Hold).unwrap();
    for interpolation in [Interpolation::Hold, Interpolation::Linear] {
        let mut h = Harness::<TimeTableFmu>::new(&Config::new()).unwrap();
        h.set_integer(&[6], &[interpolation.code()]).unwrap();
        h.initialize(0.0).unwrap();
        let mut master = table.clone();
        master.signals.interpolation = interpolation;
        let h_step = 0.125;
        for k in 0..=800 {
            let t = k as f64 * h_step;
            if k > 0 {
                h.do_step(t - h_step, h_step).unwrap();
            }
            for j in 0..2 {
                let value = master_reads(&master, j, Reading::Value, t);
                let held = master_reads(&master, j, Reading::Held, t);
                let fmu = h.real(vr(j, Reading::Value)).unwrap();
                // Bit for bit the master's value, or its held value at a missing sample.
                let expected = if value.is_nan() { held } else { value };
                assert_eq!(fmu.to_bits(), expected.to_bits(), "t = {t}, column {j}");
                assert_eq!(h.real(vr(j, Reading::Held)).unwrap(), held);
            }
        }
    }
    // An interpolation that is neither 1 nor 2 is refused when set, naming the parameter.
    let mut h = Harness::<TimeTableFmu>::new(&Config::new()).unwrap();
    assert_eq!(h.set_integer(&[6], &[3]), Err(Status::Error));
    assert!(h.logged(&["`interpolation`"]), "{:?}", h.log());
    // Hold at 1.0 s: y is missing there, held at 20.740 (0.9 s, line 11), invalid.
    let mut h = Harness::<TimeTableFmu>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    h.do_step(0.0, 1.0).unwrap();
    assert_eq!(h.real(vr(1, Reading::Value)).unwrap(), 20.74);
    assert!(!h.boolean(vr(1, Reading::Valid)).unwrap());
    assert!(h.boolean(vr(0, Reading::Valid)).unwrap());
    h.do_step(1.0, 0.1).unwrap();
    assert!(h.boolean(vr(1, Reading::Valid)).unwrap());
    assert_eq!(h.real(vr(1, Reading::Value)).unwrap(), 20.862);
}

#[test]
fn a_packaged_table_is_read_from_the_resources_linear_to_rounding() {
    let (config, dir) = packaged(RIG, Interpolation::Linear);
    let info = TimeTableFmu::describe(&config).unwrap();
    let xml = info.to_xml();
    assert!(
        xml.contains(r#"startTime="0""#) || xml.contains(r#"startTime="0.0""#),
        "{xml}"
    );
    assert!(xml.contains("interpolation linear"), "{xml}");
    assert!(xml.contains(r#"name="force.valid""#) && xml.contains(r#"unit="N""#));
    let mut h = Harness::<TimeTableFmu>::with_resources(&config, &dir).unwrap();
    h.initialize(0.0).unwrap();
    let table = DataTable::parse(RIG, Path::new("rig.csv"), Interpolation::Linear).unwrap();
    let h_step = 0.025;
    let mut worst = 0.0f64;
    for k in 1..=16 {
        let t = k as f64 * h_step;
        h.do_step(t - h_step, h_step).unwrap();
        let force = h.real(vr(0, Reading::Value)).unwrap();
        let expected = master_reads(&table, 0, Reading::Value, t);
        if expected.is_nan() {
            // Around the missing sample at 0.3: the held value −2.5 (line 4).
            assert_eq!(force, -2.5, "t = {t}");
        } else {
            worst = worst.max((force - expected).abs());
        }
    }
    assert_eq!(worst, 0.0);
    // On the line between samples (0.1, 0.7) and (0.2, −2.5): at 0.15, −0.9 to rounding.
    let mut h = Harness::<TimeTableFmu>::with_resources(&config, &dir).unwrap();
    h.initialize(0.0).unwrap();
    h.do_step(0.0, 0.15).unwrap();
    let mid = h.real(vr(0, Reading::Value)).unwrap();
    assert!((mid - -0.9).abs() <= 4.0 * f64::EPSILON, "{mid}");
}

#[test]
fn bad_tables_and_times_outside_the_samples_are_refused_by_name() {
    let (config, dir) = packaged(RIG, Interpolation::Hold);
    // The message of an instantiation whose resources/rig.csv holds `text` (None: absent).
    let refused = |text: Option<&str>| -> String {
        let dir = std::env::temp_dir().join(format!(
            "spurio-time-table-refused-{}-{}",
            std::process::id(),
            text.map_or(0, str::len)
        ));
        std::fs::create_dir_all(&dir).unwrap();
        if let Some(text) = text {
            std::fs::write(dir.join("rig.csv"), text).unwrap();
        }
        let made = Harness::<TimeTableFmu>::with_resources(&config, &dir);
        made.err().map(|e| e.to_string()).unwrap_or_default()
    };
    let err = refused(None);
    assert!(
        err.contains("rig.csv") && err.contains("(os error 2)"),
        "{err}"
    );
    // A malformed cell: file, line and column.
    let err = refused(Some(&RIG.replace("0.7", "0.7x")));
    assert!(
        err.ends_with("rig.csv, line 3, column 2 (`force`): `0.7x` is not a number (an empty cell or `nan` is a missing sample)"),
        "{err}"
    );
    // Another table than the one packaged.
    let err = refused(Some("time,force [N],x\n0,1,2\n"));
    assert!(
        err.contains("does not match the model description"),
        "{err}"
    );
    // Before the first sample, past the last.
    let mut h = Harness::<TimeTableFmu>::with_resources(&config, &dir).unwrap();
    h.setup_experiment(-0.5, None).unwrap();
    h.enter_initialization_mode().unwrap();
    assert_eq!(h.exit_initialization_mode(), Err(Status::Error));
    assert!(
        h.logged(&[
            "line 2, column 1 (`time`): the start time -0.5 is before the first sample (0)"
        ]),
        "{:?}",
        h.log()
    );
    let mut h = Harness::<TimeTableFmu>::with_resources(&config, &dir).unwrap();
    h.initialize(0.0).unwrap();
    h.do_step(0.0, 0.4).unwrap();
    assert_eq!(h.real(vr(0, Reading::Value)).unwrap(), 1e-3);
    assert_eq!(h.do_step(0.4, 0.1), Err(Status::Error));
    assert!(
        h.logged(&["line 6, column 1 (`time`): the step from 0.4 to 0.5 goes past the data, whose last sample is at 0.4"]),
        "{:?}",
        h.log()
    );
    // The instance stays where it was.
    assert_eq!(h.real(vr(0, Reading::Value)).unwrap(), 1e-3);
}

#[test]
fn reset_reads_the_table_again_and_a_state_restores_the_cursor() {
    let (config, dir) = packaged(RIG, Interpolation::Hold);
    let mut h = Harness::<TimeTableFmu>::with_resources(&config, &dir).unwrap();
    h.initialize(0.0).unwrap();
    h.do_step(0.0, 0.2).unwrap();
    let state = h.serialized_state().unwrap();
    h.do_step(0.2, 0.2).unwrap();
    assert_eq!(h.real(vr(1, Reading::Value)).unwrap(), 5.0);
    h.restore_state(&state).unwrap();
    assert_eq!(h.real(vr(1, Reading::Value)).unwrap(), 3.0);
    h.reset().unwrap();
    h.initialize(0.0).unwrap();
    assert_eq!(h.real(vr(0, Reading::Value)).unwrap(), 0.1);
}
