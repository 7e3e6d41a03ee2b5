//! Progress and cancellation through the caller's hook: a cancel takes effect within a second in
//! every phase of a large job, and progress is reported phase by phase with fractions in [0, 1].

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use wavrad::job::{self, JobError};
use wavrad::progress::{Phase, Progress};
use wavrad::scene::{parse_value, Limits};

struct Recorder {
    cancel_in: Option<(Phase, f64)>,
    cancelled: AtomicBool,
    at: Mutex<Option<Instant>>,
    seen: Mutex<Vec<(Phase, f64)>>,
}

impl Progress for Recorder {
    fn report(&self, phase: Phase, fraction: f64) {
        self.seen.lock().unwrap().push((phase, fraction));
        if let Some((p, f)) = self.cancel_in {
            if p == phase && fraction >= f && !self.cancelled.swap(true, Ordering::SeqCst) {
                *self.at.lock().unwrap() = Some(Instant::now());
            }
        }
    }
    fn cancelled(&self) -> bool {
        self.cancelled.load(Ordering::SeqCst)
    }
}

fn big_job() -> wavrad::scene::Job {
    let doc: serde_json::Value =
        serde_json::from_str(include_str!("../scenes/flatland-occluded.json")).unwrap();
    let mut doc = doc;
    doc["solver"] = serde_json::json!({"order": 2, "resolution": 256, "tolerance": 1e-14, "max_iterations": 100000});
    parse_value(&doc, &Limits::default()).unwrap()
}

#[test]
fn cancel_takes_effect_within_a_second_in_every_phase() {
    let job = big_job();
    for (phase, fraction) in [
        (Phase::Projection, 0.3),
        (Phase::Transform, 0.0),
        (Phase::Solve, 0.0),
    ] {
        let r = Recorder {
            cancel_in: Some((phase, fraction)),
            cancelled: AtomicBool::new(false),
            at: Mutex::new(None),
            seen: Mutex::new(vec![]),
        };
        let err = job::run(&job, &r).unwrap_err();
        let waited =
            r.at.lock()
                .unwrap()
                .expect("the cancel point was reached")
                .elapsed();
        assert_eq!(err, JobError::Cancelled);
        assert!(
            waited < Duration::from_secs(1),
            "{phase:?}: stopped {waited:?} after the cancel"
        );
    }
}

#[test]
fn progress_is_reported_in_order() {
    let doc: serde_json::Value =
        serde_json::from_str(include_str!("../scenes/flatland-parallel.json")).unwrap();
    let job = parse_value(&doc, &Limits::default()).unwrap();
    let r = Recorder {
        cancel_in: None,
        cancelled: AtomicBool::new(false),
        at: Mutex::new(None),
        seen: Mutex::new(vec![]),
    };
    job::run(&job, &r).unwrap();
    let seen = r.seen.lock().unwrap();
    assert!(seen.iter().all(|(_, f)| (0.0..=1.0).contains(f)));
    let phases: Vec<Phase> = seen.iter().map(|s| s.0).fold(vec![], |mut v, p| {
        if v.last() != Some(&p) {
            v.push(p);
        }
        v
    });
    assert_eq!(
        phases,
        [
            Phase::Projection,
            Phase::Transform,
            Phase::Solve,
            Phase::Metrics
        ]
    );
    assert!(seen
        .iter()
        .any(|&(p, f)| p == Phase::Projection && f == 1.0));
}

#[test]
fn cancel_stops_the_hierarchical_method_within_a_second() {
    let mut doc: serde_json::Value =
        serde_json::from_str(include_str!("../scenes/flatland-room.json")).unwrap();
    doc["solver"] = serde_json::json!({"method": "hierarchical", "order": 2, "resolution": 1024,
        "epsilon": 1e-7, "tolerance": 1e-14, "max_iterations": 100000});
    let job = parse_value(&doc, &Limits::default()).unwrap();
    let r = Recorder {
        cancel_in: Some((Phase::Refinement, 0.0)),
        cancelled: AtomicBool::new(false),
        at: Mutex::new(None),
        seen: Mutex::new(vec![]),
    };
    assert_eq!(job::run(&job, &r).unwrap_err(), JobError::Cancelled);
    let waited = r.at.lock().unwrap().unwrap().elapsed();
    assert!(
        waited < Duration::from_secs(1),
        "stopped {waited:?} after the cancel"
    );
}

/// Cancels `after` into the job (as a DELETE or a job timeout would), wherever it is.
struct CancelAt {
    start: Instant,
    after: Duration,
}

impl Progress for CancelAt {
    fn report(&self, _: Phase, _: f64) {}
    fn cancelled(&self) -> bool {
        self.start.elapsed() >= self.after
    }
}

#[test]
fn cancel_stops_a_fine_3d_refinement_within_a_second() {
    // the Cornell box at ε = 6.25e-5 refines for several seconds, a level at a time, each
    // level's pairs judged in parallel with their rays; cancels at several points of it
    let mut doc: serde_json::Value =
        serde_json::from_str(include_str!("../scenes/cornell-box.json")).unwrap();
    doc["solver"]["epsilon"] = serde_json::json!(6.25e-5);
    let job = parse_value(&doc, &Limits::default()).unwrap();
    // a pool of its own, as the server gives each job
    let pool = rayon::ThreadPoolBuilder::new().build().unwrap();
    for after in [0.3, 1.0, 2.0, 3.0] {
        let p = CancelAt {
            start: Instant::now(),
            after: Duration::from_secs_f64(after),
        };
        assert_eq!(
            pool.install(|| job::run(&job, &p)).unwrap_err(),
            JobError::Cancelled
        );
        let waited = p.start.elapsed().as_secs_f64() - after;
        assert!(
            waited < 1.0,
            "cancelled at {after} s, stopped {waited:.2} s later"
        );
    }
}
