//! `tre ros2` as a child process of the test: started and waited for, its log read as it
//! comes, stopped by SIGTERM, and its log checked.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `tre ros2` as a child process, killed on drop: its stdout past the first line, and its
/// stderr as it comes (read on a thread of its own, so a test can wait for a log line).
pub(super) struct Tre {
    child: Option<Child>,
    stdout: Option<std::io::BufReader<std::process::ChildStdout>>,
    first: String,
    pub(super) log: std::sync::Arc<std::sync::Mutex<String>>,
    log_thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Tre {
    fn drop(&mut self) {
        if let Some(c) = &mut self.child {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Tre {
    /// Waits until `needle` is in the log; false after `wait`.
    pub(super) fn wait_for_log(&self, needle: &str, wait: Duration) -> bool {
        let deadline = Instant::now() + wait;
        while Instant::now() < deadline {
            if self.log.lock().unwrap().contains(needle) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

pub(super) fn start_tre(args: &[&str]) -> Tre {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("ros2")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let log = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
    let stderr = child.stderr.take().unwrap();
    let sink = std::sync::Arc::clone(&log);
    let log_thread = std::thread::Builder::new()
        .name("tre-ros2-stderr".into())
        .spawn(move || {
            for line in std::io::BufRead::lines(std::io::BufReader::new(stderr)) {
                let Ok(line) = line else { break };
                let mut l = sink.lock().unwrap();
                l.push_str(&line);
                l.push('\n');
            }
        })
        .unwrap();
    // The node prints one line once it has joined the domain.
    let mut first = String::new();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    std::io::BufRead::read_line(&mut out, &mut first).unwrap();
    if first.is_empty() {
        let _ = child.wait();
        let _ = log_thread.join();
        panic!("tre ros2 did not start: {}", log.lock().unwrap());
    }
    assert!(first.starts_with("ros2 node"), "{first}");
    Tre {
        child: Some(child),
        stdout: Some(out),
        first,
        log,
        log_thread: Some(log_thread),
    }
}

/// `tre ros2` stopped by SIGTERM: its exit status, stdout and stderr.
pub(super) fn stop_tre(mut tre: Tre) -> (bool, String, String) {
    let mut child = tre.child.take().unwrap();
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    let mut stdout = tre.first.clone();
    std::io::Read::read_to_string(&mut tre.stdout.take().unwrap(), &mut stdout).unwrap();
    let status = child.wait().unwrap();
    if let Some(t) = tre.log_thread.take() {
        t.join().unwrap();
    }
    let stderr = tre.log.lock().unwrap().clone();
    (status.success(), stdout, stderr)
}

/// A clean stop logs nothing at error level: the node takes its publishers, subscriptions,
/// node, spinner and participant down in the order the DDS libraries need (else they print
/// "Cannot remove Reader/Writer" and "Cannot notify spin task" errors).
pub(super) fn assert_no_errors_at_stop(stderr: &str) {
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| {
            l.contains("ERROR") || l.contains("Cannot remove") || l.contains("Cannot notify")
        })
        .collect();
    assert!(
        errors.is_empty(),
        "errors logged: {errors:#?}\nin: {stderr}"
    );
}

/// Quiet logs at the default level while running: nothing from the DDS libraries, at most a
/// line a frame.
pub(super) fn assert_quiet_while_running(tre: &Tre, frames: usize) {
    let running = tre.log.lock().unwrap().clone();
    assert!(
        !running.contains("rustdds") && !running.contains("ros2_client"),
        "{running}"
    );
    assert!(
        running.lines().count() <= frames,
        "{} log lines for {} frames: {running}",
        running.lines().count(),
        frames
    );
}
