//! A memory and disk soak: a started `wavrad serve` process is sent many jobs one after
//! another, and its resident memory (VmRSS, and RssAnon, the heap's part of it) and the size
//! of its `data_dir` are sampled after each. Three phases:
//!
//! 1. `WAVRAD_BENCH_CORNELL` (100) Cornell boxes (`scenes/cornell-box.json`, each with its own
//!    scene name, so that none is answered from an earlier job), `POST /api/v1/render`;
//! 2. 600 reads of `image.png` of the Cornell boxes still kept;
//! 3. small flatland jobs of mixed sizes (2 segments, order 0 to 2, 8 to 128 cells), with a
//!    Cornell box every 25th, up to `WAVRAD_BENCH_JOBS` (1000) jobs in all.
//!
//! The server keeps at most `WAVRAD_BENCH_MAX_STORE_BYTES` (`200MB`) of jobs, so the disk
//! should level off once that much is stored. Prints the figures of `benches/README.md`
//! ("Memory and disk") and draws `benches/soak.png` (memory and disk against jobs posted).
//! Linux only (it reads `/proc`).
//!
//! `cargo bench --bench soak`

#[path = "../tests/listening/mod.rs"]
mod listening;

use plotters::prelude::*;
use serde_json::{json, Value};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

struct Server {
    child: Child,
    base: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A field of `/proc/PID/status` in kB, as MB.
fn status_mb(pid: u32, field: &str) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("the field in /proc/PID/status");
    kb / 1024.0
}

/// Resident memory of a process, MB.
fn rss_mb(pid: u32) -> f64 {
    status_mb(pid, "VmRSS:")
}

/// The anonymous part of the resident memory (the heap; the rest is the mapped binary and
/// libraries: the store is read and written, not mapped), MB.
fn anon_mb(pid: u32) -> f64 {
    status_mb(pid, "RssAnon:")
}

/// Bytes of the files under `dir` (their lengths), MB.
fn disk_mb(dir: &Path) -> f64 {
    fn walk(dir: &Path) -> u64 {
        std::fs::read_dir(dir)
            .map(|rd| {
                rd.flatten()
                    .map(|e| match e.metadata() {
                        Ok(m) if m.is_dir() => walk(&e.path()),
                        Ok(m) => m.len(),
                        Err(_) => 0,
                    })
                    .sum()
            })
            .unwrap_or(0)
    }
    walk(dir) as f64 / 1e6
}

fn env(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.into())
}

fn cornell(i: usize) -> Value {
    let mut d: Value = serde_json::from_str(include_str!("../scenes/cornell-box.json")).unwrap();
    d["scene"]["name"] = json!(format!("Cornell box {i}"));
    d
}

fn flatland(i: usize) -> Value {
    let mut d: Value =
        serde_json::from_str(include_str!("../scenes/flatland-parallel.json")).unwrap();
    d["scene"]["name"] = json!(format!("soak {i}"));
    d["solver"]["order"] = json!(i % 3);
    d["solver"]["resolution"] = json!(8 << (i % 5));
    d
}

struct Sample {
    jobs: usize,
    rss: f64,
    anon: f64,
    disk: f64,
}

/// What one panel of the plot shows of a sample.
type Metric = fn(&Sample) -> f64;

fn main() {
    let total: usize = env("WAVRAD_BENCH_JOBS", "1000").parse().unwrap();
    let cornells: usize = env("WAVRAD_BENCH_CORNELL", "100").parse().unwrap();
    let max_store = env("WAVRAD_BENCH_MAX_STORE_BYTES", "200MB");
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args(["serve", "--addr", "127.0.0.1:0", "--queue-capacity", "1000"])
        .args(["--max-store-bytes", &max_store])
        .arg("--data-dir")
        .arg(dir.path())
        .env("WAVRAD_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let base = listening::base_url(&mut child);
    let server = Server { child, base };
    let pid = server.child.id();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let http = reqwest::Client::new();
    let render = |doc: Value| {
        let http = http.clone();
        let url = format!("{}/api/v1/render", server.base);
        async move {
            let r = http
                .post(url)
                .header("content-type", "application/json")
                .header("accept", "application/json")
                .body(doc.to_string())
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
            let location = r.headers()["content-location"]
                .to_str()
                .unwrap()
                .to_string();
            r.bytes().await.unwrap();
            location
        }
    };
    let start = Instant::now();
    let mut samples = vec![Sample {
        jobs: 0,
        rss: rss_mb(pid),
        anon: anon_mb(pid),
        disk: disk_mb(dir.path()),
    }];
    println!("started: RSS {:.1} MB", samples[0].rss);
    let sample = |jobs: usize, samples: &mut Vec<Sample>| {
        let s = Sample {
            jobs,
            rss: rss_mb(pid),
            anon: anon_mb(pid),
            disk: disk_mb(dir.path()),
        };
        if [1, 10, 20, 50, 100].contains(&jobs) || jobs.is_multiple_of(100) {
            println!(
                "{jobs:>5} jobs, {:>6.1} s: RSS {:.1} MB (anonymous {:.1}), data_dir {:.1} MB",
                start.elapsed().as_secs_f64(),
                s.rss,
                s.anon,
                s.disk
            );
        }
        samples.push(s);
    };
    // 1. Cornell boxes
    let mut kept = Vec::new();
    for i in 0..cornells {
        kept.push(runtime.block_on(render(cornell(i))));
        sample(i + 1, &mut samples);
        if [10, 50].contains(&(i + 1)) || i + 1 == cornells {
            // right after a job the last solve's memory may not be returned yet: settled
            std::thread::sleep(std::time::Duration::from_secs(2));
            println!(
                "after {} Cornell boxes, settled: RSS {:.1} MB (anonymous {:.1})",
                i + 1,
                rss_mb(pid),
                anon_mb(pid)
            );
        }
    }
    println!(
        "data_dir after {cornells} Cornell boxes: {:.1} MB (the files' lengths)",
        samples.last().unwrap().disk
    );
    // 2. 600 reads of image.png, of the jobs still kept
    let before = rss_mb(pid);
    let mut reads = 0;
    runtime.block_on(async {
        for location in kept.iter().rev().cycle().take(600 * 4) {
            let r = http
                .get(format!("{}{location}/image.png", server.base))
                .send()
                .await
                .unwrap();
            if r.status() == 200 {
                r.bytes().await.unwrap();
                reads += 1;
                if reads == 600 {
                    break;
                }
            }
        }
    });
    let after = rss_mb(pid);
    println!("600 reads of image.png ({reads} found): RSS {before:.1} → {after:.1} MB");
    samples.push(Sample {
        jobs: cornells,
        rss: after,
        anon: anon_mb(pid),
        disk: disk_mb(dir.path()),
    });
    // 3. mixed sizes
    for i in cornells..total {
        let doc = if i.is_multiple_of(25) {
            cornell(i)
        } else {
            flatland(i)
        };
        runtime.block_on(render(doc));
        sample(i + 1, &mut samples);
    }
    std::thread::sleep(std::time::Duration::from_secs(2));
    println!(
        "settled: RSS {:.1} MB (anonymous {:.1})",
        rss_mb(pid),
        anon_mb(pid)
    );
    let last = samples.last().unwrap();
    println!(
        "after {total} jobs, {:.0} s: RSS {:.1} MB, data_dir {:.1} MB (max_store_bytes {max_store})",
        start.elapsed().as_secs_f64(),
        last.rss,
        last.disk
    );
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/soak.png");
    plot(&samples, cornells, &max_store, &out);
    println!("plot: {}", out.display());
    drop(server);
}

fn plot(samples: &[Sample], cornells: usize, max_store: &str, out: &Path) {
    let font: &'static [u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
    plotters::style::register_font("sans-serif", FontStyle::Normal, font)
        .map_err(|_| ())
        .expect("the font parses");
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        let panels = root.split_evenly((2, 1));
        let x_max = samples.iter().map(|s| s.jobs).max().unwrap_or(1).max(1);
        let series: [(&str, Metric, RGBColor); 2] = [
            ("resident memory (MB)", |s| s.rss, RGBColor(31, 119, 180)),
            ("data_dir (MB)", |s| s.disk, RGBColor(214, 39, 40)),
        ];
        for (panel, (label, value, color)) in panels.iter().zip(series) {
            let y_max = samples.iter().map(value).fold(1.0, f64::max) * 1.1;
            let caption = if label.starts_with("resident") {
                format!(
                "wavrad serve: resident memory; {cornells} Cornell boxes, 600 image reads, then mixed jobs"
            )
            } else {
                format!("data_dir on disk, max_store_bytes = {max_store}")
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(caption, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(55)
                .build_cartesian_2d(0usize..x_max, 0.0..y_max)
                .unwrap();
            chart
                .configure_mesh()
                .x_desc("jobs posted")
                .y_desc(label)
                .label_style(("sans-serif", 12))
                .draw()
                .unwrap();
            chart
                .draw_series(LineSeries::new(
                    samples.iter().map(|s| (s.jobs, value(s))),
                    color.stroke_width(2),
                ))
                .unwrap()
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
            if label.starts_with("resident") {
                let anon = RGBColor(44, 160, 44);
                chart
                    .draw_series(LineSeries::new(
                        samples.iter().map(|s| (s.jobs, s.anon)),
                        anon.stroke_width(2),
                    ))
                    .unwrap()
                    .label("of which anonymous (heap) (MB)")
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], anon));
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::LowerRight)
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK.mix(0.3))
                    .label_font(("sans-serif", 12))
                    .draw()
                    .unwrap();
            }
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(cornells, 0.0), (cornells, y_max)],
                    BLACK.mix(0.3),
                )))
                .unwrap();
        }
        root.present().unwrap();
    }
    image::RgbImage::from_raw(w, h, buf)
        .expect("w × h × 3 bytes")
        .save(out)
        .unwrap();
}
