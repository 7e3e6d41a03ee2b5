//! Bad input gets errors, never a panic: a few thousand random mutations of the example
//! documents go through validation, and the small ones that validate are solved.

use serde_json::{json, Value};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 17
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn leaves(v: &Value, path: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => m
            .iter()
            .for_each(|(k, x)| leaves(x, format!("{path}/{k}"), out)),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .for_each(|(i, x)| leaves(x, format!("{path}/{i}"), out)),
        _ => {}
    }
    out.push(path);
}

fn nasty(r: &mut Lcg) -> Value {
    match r.below(14) {
        0 => json!(null),
        1 => json!(-1),
        2 => json!(0),
        3 => json!(1e308),
        4 => json!(-1e-308),
        5 => json!("x^"),
        6 => json!([]),
        7 => json!({}),
        8 => json!([1, 2, 3, 4]),
        9 => json!(0.999_999_999),
        10 => json!(true),
        11 => json!("1/0 + ln(x)"),
        12 => json!(3),
        _ => json!(r.below(5000) as f64 / 100.0 - 10.0),
    }
}

#[test]
fn random_mutations_never_panic() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let docs: Vec<Value> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap())
        .collect();
    let mut r = Lcg(42);
    let (mut valid, mut invalid) = (0, 0);
    for round in 0..3000 {
        let mut doc = docs[round % docs.len()].clone();
        let mut paths = Vec::new();
        leaves(&doc, String::new(), &mut paths);
        for _ in 0..1 + r.below(3) {
            let p = &paths[r.below(paths.len())];
            if let Some(slot) = doc.pointer_mut(p) {
                *slot = nasty(&mut r);
            }
        }
        match parse_value(&doc, &Limits::default()) {
            Ok(job) => {
                valid += 1;
                if job.basis_size() <= 256 && job.scene.kind.name() != "3d" {
                    // a solve may fail (diverge) but must not panic
                    let _ = wavrad::job::run(&job, &Silent);
                }
            }
            Err(errors) => {
                invalid += 1;
                assert!(!errors.0.is_empty());
                for e in &errors.0 {
                    assert!(e.path.is_empty() || e.path.starts_with('/'), "{e}");
                    assert!(!e.message.is_empty());
                }
            }
        }
    }
    assert!(
        valid > 100 && invalid > 1000,
        "{valid} valid, {invalid} invalid"
    );
}
