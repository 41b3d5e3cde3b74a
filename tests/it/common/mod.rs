//! Helpers shared by the service's integration tests: a real `tre serve` on a loopback port,
//! stopped on drop, and the `tre infer` reference a service answer must equal.
#![allow(dead_code, clippy::unwrap_used)] // Not every test file uses every helper.

pub(crate) mod stream;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A `tre serve` child process on 127.0.0.1, killed when dropped.
pub(crate) struct Server {
    child: Child,
    /// Its address.
    pub addr: SocketAddr,
}

impl Server {
    /// Starts `tre serve` with `args` (plus loopback address, committed models, one ORT
    /// thread) and waits until `/readyz` answers 200.
    pub(crate) fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["serve", "--addr", "127.0.0.1:0", "--ort-threads", "1"])
            .args(args)
            .env("TRE_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starts tre serve");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let addr: SocketAddr = line
            .trim()
            .strip_prefix("listening on http://")
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .parse()
            .unwrap();
        let server = Self { child, addr };
        let start = Instant::now();
        while get(addr, "/readyz").0 != 200 {
            assert!(
                start.elapsed() < Duration::from_secs(180),
                "not ready after 180 s"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        server
    }

    /// `http://ADDR`.
    pub(crate) fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// The process id.
    pub(crate) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether the process is still running.
    pub(crate) fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }

    /// Resident set size, KiB, from /proc.
    pub(crate) fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).unwrap();
        let line = status.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    }

    /// Sends SIGTERM and waits for the exit status.
    pub(crate) fn terminate(mut self) -> std::process::ExitStatus {
        Command::new("kill")
            .args(["-TERM", &self.pid().to_string()])
            .status()
            .unwrap();
        let status = self.child.wait().unwrap();
        // The child has exited: skip the Drop, which would kill and reap it a second time.
        #[allow(clippy::mem_forget)]
        std::mem::forget(self);
        status
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A plain HTTP/1.1 GET: status and body.
pub(crate) fn get(addr: SocketAddr, path: &str) -> (u16, Vec<u8>) {
    let Ok(mut s) = TcpStream::connect(addr) else {
        return (0, Vec::new());
    };
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    if s.write_all(req.as_bytes()).is_err() {
        return (0, Vec::new());
    }
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let text = String::from_utf8_lossy(&raw);
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map_or_else(Vec::new, |i| raw[i + 4..].to_vec());
    (status, body)
}

/// The shared data beside the repository: `$TRE_SHARED_DIR` where that is set, else
/// `<repository>/../shared` (CI has it there; a clone of the repository alone does not).
pub(crate) fn shared_root() -> PathBuf {
    match std::env::var_os("TRE_SHARED_DIR") {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared"),
    }
}

/// `rel` (a folder such as `data/real-rgbd`) under the shared data, where it is there. Where it
/// is not, the calling test is to return early: this prints one line saying so to stderr (past
/// the harness's capture, so that a skip is never silent) and gives `None`, unless
/// `TRE_REQUIRE_SHARED=1` (as in CI), which makes the missing folder a failure.
pub(crate) fn shared_data(rel: &str) -> Option<PathBuf> {
    let path = shared_root().join(rel);
    if path.is_dir() {
        return Some(path);
    }
    let needs = Path::new("../shared").join(rel);
    if std::env::var("TRE_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
        panic!(
            "TRE_REQUIRE_SHARED=1: {} is required beside the repository, and {} is missing",
            needs.display(),
            path.display()
        );
    }
    let test = std::thread::current().name().unwrap_or("a test").to_owned();
    let line = format!(
        "skipped {test}: needs {} beside the repository ({} is missing)\n",
        needs.display(),
        path.display()
    );
    let _ = std::io::stderr().write_all(line.as_bytes());
    None
}

/// Returns from the calling test unless the shared folder `rel` is there ([`shared_data`],
/// which says so on stderr, or fails under `TRE_REQUIRE_SHARED=1`); `return VALUE` in a test
/// that returns one: `skip_unless_shared!("data/real-rgbd", Ok(()))`.
#[allow(unused_macros)] // Not every binary that includes this file skips.
macro_rules! skip_unless_shared {
    ($rel:expr) => {
        if $crate::common::shared_data($rel).is_none() {
            return;
        }
    };
    ($rel:expr, $value:expr) => {
        if $crate::common::shared_data($rel).is_none() {
            return $value;
        }
    };
}
#[allow(unused_imports)] // Not every binary that includes this file skips.
pub(crate) use skip_unless_shared;

/// A file of the real RGB-D frames in `../shared/data/real-rgbd`. A test that reads them
/// returns early unless they are there: [`skip_unless_shared`].
pub(crate) fn real(rel: &str) -> PathBuf {
    shared_root().join("data/real-rgbd").join(rel)
}

/// The repository's root (the `tre` package's folder).
pub(crate) fn repo_root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The text of `rel`, a file of the repository; failing that, a failure that names the file.
pub(crate) fn repo_text(rel: &str) -> String {
    let path = repo_root().join(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// The `tre` binary as a test runs it: from the package root, with one ORT thread.
pub(crate) fn tre_command() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tre"));
    command
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TRE_ORT_THREADS", "1");
    command
}

/// `tre ARGS` run to its end ([`tre_command`]): its status and output.
pub(crate) fn tre(args: &[&str]) -> Output {
    tre_command().args(args).output().expect("runs tre")
}

/// The stderr of a finished command, as text.
pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A path as a command-line argument (the tests' paths are UTF-8).
pub(crate) fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A multi-threaded runtime for a test's client.
pub(crate) fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap()
}

/// A 2-D `.npy` written by `tre` (`tre map`'s layers, `--format npy` maps) as float32: its
/// shape (rows, columns) and its values, row by row.
pub(crate) fn npy_f32(path: &Path) -> ((usize, usize), Vec<f32>) {
    let a = tre::io::npy::read_npy(std::fs::File::open(path).unwrap()).unwrap();
    let g = tre::io::npy_grid(a).unwrap();
    (
        (g.height(), g.width()),
        g.as_slice().iter().map(|&v| v as f32).collect(),
    )
}

/// Runs `tre infer` with `args` writing a 16-bit PNG, and returns its raw grey+alpha values.
pub(crate) fn infer_png16(args: &[&str]) -> (u32, u32, Vec<u16>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TRE_ORT_THREADS", "1")
        .arg("infer")
        .args(args)
        .args(["-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "tre infer failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    png16_values(&std::fs::read(&out).unwrap())
}

/// Width, height and raw grey+alpha values of a 16-bit grey+alpha PNG.
pub(crate) fn png16_values(bytes: &[u8]) -> (u32, u32, Vec<u16>) {
    let img = image::load_from_memory(bytes).unwrap();
    assert_eq!(
        img.color(),
        image::ColorType::La16,
        "not a 16-bit grey+alpha PNG"
    );
    let la = img.to_luma_alpha16();
    (la.width(), la.height(), la.into_raw())
}

/// A PNG of the given size with a hand-written IHDR (for sizes no encoder writes: 0×0, or a
/// huge declared size with almost no data).
pub(crate) fn png_with_header(width: u32, height: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    // A zlib stream of a few zero bytes: far too little data for the declared size.
    chunk(
        &mut png,
        b"IDAT",
        &[0x78, 0x9c, 0x63, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01],
    );
    chunk(&mut png, b"IEND", &[]);
    png
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let mut crc_input = kind.to_vec();
    crc_input.extend_from_slice(data);
    out.extend_from_slice(&crc32(&crc_input).to_be_bytes());
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// An RGB PNG of `w`×`h`, a deterministic pattern.
pub(crate) fn pattern_png(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x * 7 % 256) as u8,
            (y * 5 % 256) as u8,
            ((x + y) % 256) as u8,
        ])
    });
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// `std::thread::spawn` with a name, so that a panic or a hang says which helper thread it was
/// (unnamed threads are disallowed by the workspace's lints).
pub(crate) fn spawn_named<T, F>(name: &str, f: F) -> std::thread::JoinHandle<T>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    std::thread::Builder::new()
        .name(name.to_string())
        .spawn(f)
        .expect("the test thread starts")
}

/// A synthetic-dataset configuration writing to `out`: `scenes` scenes of `views` views each at
/// `size` (width, height), drawn from `seed`; every other setting is the default.
pub(crate) fn synth_config(
    out: &Path,
    scenes: u32,
    seed: u64,
    size: (usize, usize),
    views: u32,
) -> tre::synth::dataset::SynthConfig {
    tre::synth::dataset::SynthConfig {
        out: out.to_owned(),
        scenes,
        seed,
        size,
        views,
        ..tre::synth::dataset::SynthConfig::default()
    }
}

/// One of the real frames, as `tests/fixtures/real_floor.json` lists it.
#[derive(serde::Deserialize)]
pub(crate) struct RealFrame {
    /// Its folder under the real frames ([`real`]).
    pub dir: String,
    /// Its depth image, relative to `dir`.
    pub depth: String,
    /// A box of flat floor `[x0, y0, x1, y1]` (pixels, ends excluded), where it has one.
    pub floor: Option<[usize; 4]>,
}

impl RealFrame {
    /// Its depth (metres) and the intrinsics of its depth image.
    pub(crate) fn depth(&self) -> (tre::geometry::Grid<f64>, tre::geometry::Intrinsics) {
        let dir = real(&self.dir);
        let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).unwrap();
        let depth = tre::io::read_depth(&dir.join(&self.depth), cam.depth_scale.unwrap()).unwrap();
        (depth, k)
    }
}

/// The real frames of `tests/fixtures/real_floor.json`.
pub(crate) fn real_frames() -> Vec<RealFrame> {
    #[derive(serde::Deserialize)]
    struct Fixture {
        frames: Vec<RealFrame>,
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/real_floor.json");
    let fixture: Fixture = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    fixture.frames
}

/// The spec (annotation spec v1, default settings) on a depth map alone.
pub(crate) fn spec(
    depth: &tre::geometry::Grid<f64>,
    k: &tre::geometry::Intrinsics,
) -> tre::roughness::annotate::Annotation {
    tre::roughness::annotate::annotate(
        &tre::roughness::annotate::AnnotateInput::depth(depth, k),
        &tre::roughness::annotate::AnnotateConfig::default(),
    )
    .unwrap()
}

/// `scripts/check_mcap.py RECORD ARGS…` (the Python `mcap` and `mcap-ros2-support` packages
/// reading a recording): it must pass. Skipped, saying so, without such a Python unless
/// `TRE_REQUIRE_SHARED=1`.
pub(crate) fn check_mcap(record: &Path, args: &[&str]) {
    let Some(python) = mcap_python() else { return };
    let o = Command::new(python)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check_mcap.py"))
        .arg(record)
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "check_mcap.py {args:?}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A Python with `mcap` and `mcap_ros2`: `$TRE_MCAP_PYTHON`, else CI's virtualenv. Without one
/// the check is skipped, saying so, unless `TRE_REQUIRE_SHARED=1` (as in CI).
fn mcap_python() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("TRE_MCAP_PYTHON").map(PathBuf::from),
        Some(Path::new(env!("CARGO_MANIFEST_DIR")).join(".ci/.venv-py/bin/python")),
    ];
    for p in candidates.into_iter().flatten() {
        let ok = Command::new(&p)
            .args(["-c", "import mcap, mcap_ros2, numpy"])
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return Some(p);
        }
    }
    assert!(
        std::env::var("TRE_REQUIRE_SHARED").map_or(true, |v| v != "1"),
        "TRE_REQUIRE_SHARED=1: the recording check needs a Python with mcap, mcap-ros2-support \
         and numpy (TRE_MCAP_PYTHON, or .ci/.venv-py as .ci/run makes it)"
    );
    eprintln!("skipped the recording check: no Python with mcap and mcap-ros2-support");
    None
}
