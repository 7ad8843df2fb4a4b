//! What the export-layer test suites (FMI 2.0 `export_layer.rs`, FMI 3.0 `fmi3_layer.rs`)
//! share: the toy model and the stderr check.

pub mod toy;

/// Runs the test `child` of this test binary in a child process (with `SPURIO_PANIC_CHILD`
/// set, so that it does its work) and asserts that it passed and that the only line it wrote
/// on stderr is its own `child done`: a panic inside an FMU call prints nothing there.
///
/// Under an emulator (the aarch64 suites run in qemu-user, `tests/platforms/rust-suites`), the
/// child is started through the command in `SPURIO_TEST_RUNNER` (e.g. `qemu-aarch64 -L
/// /usr/aarch64-linux-gnu`), as cargo starts the test binary itself.
pub fn assert_child_prints_only_its_line(child: &str) {
    let runner = std::env::var("SPURIO_TEST_RUNNER").unwrap_or_default();
    let mut runner = runner.split_whitespace();
    let exe = std::env::current_exe().unwrap();
    let mut command = match runner.next() {
        Some(program) => {
            let mut c = std::process::Command::new(program);
            c.args(runner).arg(exe);
            c
        }
        None => std::process::Command::new(exe),
    };
    command
        .args(["--exact", child, "--nocapture", "--test-threads=1"])
        .env("SPURIO_PANIC_CHILD", "1")
        .env("RUST_BACKTRACE", "1");
    // Starting the child is not what is tested: under wine on a loaded machine process
    // creation itself can fail now and then (ERROR_INTERNAL_ERROR, 1359), so a failed start
    // is tried again, up to three times; what the child then prints is checked once.
    let mut attempt = 0;
    let output = loop {
        match command.output() {
            Ok(output) => break output,
            Err(e) if attempt < 2 => {
                attempt += 1;
                eprintln!("starting the child failed ({e}); trying again");
                std::thread::sleep(std::time::Duration::from_millis(200));
            }
            Err(e) => panic!("starting the child failed three times: {e}"),
        }
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "child failed: {stdout}\n{stderr}");
    assert!(stdout.contains("1 passed"), "{stdout}");
    // the only line on stderr is the child's own
    assert_eq!(stderr.trim(), "child done", "{stderr}");
}
