//! The streaming client against the real `tre serve` binary over loopback: every frame's result
//! comes back and equals `tre infer` on the same frame, value for value, alpha mask included;
//! `tre client` writes one PNG and one CSV row per frame (also through the ffmpeg pipe route,
//! with a stand-in `ffmpeg`), and fails when nothing comes back; a session whose server is
//! killed reports the frame in flight lost, reconnects to a new server on the same port and
//! carries on.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use common::{check_mcap, get, infer_png16, png16_values, real, rt};
use image::DynamicImage;
use tre::client::{ClientConfig, Event, Frame, LostReason, Rate, Session};
use tre::pipeline::{Mode, NormalsMethod};

mod depth;
mod depth_only;
mod frames;
mod reconnect;
mod tls;

/// One test at a time: each starts servers, and the machine has few cores.
static SERIAL: Mutex<()> = Mutex::new(());

/// What a test starts with: the other tests waited for ([`SERIAL`]), a temporary folder, and a
/// `tre serve` on a free loopback port with `more` options, logging to `serve.log` in it. Not
/// waited for: `tre client` waits for readiness itself, and a test that needs the server ready
/// first calls [`Server::wait_ready`].
fn serve(more: &[&str]) -> (MutexGuard<'static, ()>, tempfile::TempDir, Server) {
    let serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start_with("127.0.0.1:0", &dir.path().join("serve.log"), more);
    (serial, dir, server)
}

/// A `tre serve` child process at a chosen address (so that a second one can take the first's
/// port), killed on drop; its log goes to a file.
struct Server {
    child: Child,
    addr: SocketAddr,
    log: PathBuf,
    _stdout: BufReader<ChildStdout>,
}

impl Server {
    /// Starts `tre serve --addr ADDR --workers 1` and reads the address it listens on.
    fn start(addr: &str, log: &Path) -> Self {
        Self::start_with(addr, log, &[])
    }

    /// [`Server::start`] with more options.
    fn start_with(addr: &str, log: &Path, more: &[&str]) -> Self {
        let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
            .args([
                "serve",
                "--addr",
                addr,
                "--workers",
                "1",
                "--ort-threads",
                "1",
            ])
            .args(more)
            .arg("--models")
            .arg(models)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let Some(url) = line.trim().strip_prefix("listening on http://") else {
            let _ = child.kill();
            panic!(
                "no listening line: {line:?}; log: {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        };
        Self {
            addr: url.parse().unwrap(),
            child,
            log: log.to_owned(),
            _stdout: stdout,
        }
    }

    /// Polls `GET /readyz` until it answers 200.
    fn wait_ready(&self) {
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(300) {
            if get(self.addr, "/readyz").0 == 200 {
                return;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        panic!(
            "not ready after 300 s; log: {}",
            std::fs::read_to_string(&self.log).unwrap_or_default()
        );
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Small frames (160×120 PNGs) made from the real Kinect frames in `../shared/data/real-rgbd`.
fn make_frames(dir: &Path) -> Vec<(String, PathBuf)> {
    let sources = [
        ("a_ch7_1", real("slambook2_ch7/1.png")),
        ("b_ch5_3", real("slambook2_ch5/color/3.png")),
        ("c_nyu_50", real("metric3d_nyu/rgb/rgb_00050.jpg")),
        ("d_ch7_2", real("slambook2_ch7/2.png")),
    ];
    std::fs::create_dir_all(dir).unwrap();
    sources
        .iter()
        .map(|(name, src)| {
            let img = image::open(src).unwrap().to_rgb8();
            let small =
                image::imageops::resize(&img, 160, 120, image::imageops::FilterType::Triangle);
            let path = dir.join(format!("{name}.png"));
            tre::io::save(&path, &DynamicImage::ImageRgb8(small)).unwrap();
            ((*name).to_owned(), path)
        })
        .collect()
}

fn session_config(addr: SocketAddr) -> ClientConfig {
    ClientConfig {
        server: format!("ws://{addr}/v1/stream"),
        mode: Some(Mode::Rgb),
        seed: 0,
        normals: Some(NormalsMethod::Dsac),
        rate: Rate::AsFastAsResults,
        frame_timeout: Duration::from_secs(120),
        ..ClientConfig::default()
    }
}

/// The next event, failing the test after two minutes of silence.
async fn next(events: &mut tre::client::Events) -> Event {
    tokio::time::timeout(Duration::from_secs(120), events.recv())
        .await
        .expect("no event within 120 s")
        .expect("the session ended early")
}
