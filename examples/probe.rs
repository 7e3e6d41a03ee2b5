use serde_json::{json, Value};
use wavrad::{
    job,
    progress::Silent,
    scene::{parse_value, Limits},
};
fn run(doc: &Value, solver: Value) -> wavrad::job::Outcome {
    let mut d = doc.clone();
    d["solver"] = solver;
    d["output"] = json!({"grid": 16});
    let j = parse_value(&d, &Limits::default()).unwrap();
    job::run(&j, &Silent).unwrap()
}
fn cells(o: &wavrad::job::Outcome) -> Vec<f64> {
    o.result
        .surfaces
        .iter()
        .flat_map(|s| s.cells.iter().map(|c| c[0]))
        .collect()
}
fn rel(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    (d / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
}
fn main() {
    let name = std::env::args().nth(1).unwrap();
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&name).unwrap()).unwrap();
    let reference = cells(&run(
        &doc,
        json!({"order": 3, "resolution": 128, "tolerance": 1e-12}),
    ));
    {
        let o = run(
            &doc,
            json!({"method": "hierarchical", "order": 0, "resolution": 256, "epsilon": 1e-5, "tolerance": 1e-10}),
        );
        let r = run(
            &doc,
            json!({"order": 3, "resolution": 128, "tolerance": 1e-12}),
        );
        for (a, b) in o.result.surfaces.iter().zip(&r.result.surfaces) {
            let x: Vec<f64> = a.cells.iter().map(|c| c[0]).collect();
            let y: Vec<f64> = b.cells.iter().map(|c| c[0]).collect();
            println!(
                "{}: {:.2e} {:?}\n   ref {:?}",
                a.name,
                rel(&x, &y),
                &x[..6],
                &y[..6]
            );
        }
        println!(
            "energy {:?} vs {:?}",
            o.result.metrics.energy.balance, r.result.metrics.energy.balance
        );
    }
    for m in [0, 1, 2] {
        for eps in [1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5] {
            let t = std::time::Instant::now();
            let o = run(
                &doc,
                json!({"method": "hierarchical", "order": m, "resolution": 256, "epsilon": eps, "tolerance": 1e-10}),
            );
            let h = o.result.hierarchical.as_ref().unwrap();
            println!("m={m} eps={eps:e}: err={:.2e} leaves={} links={} elements={} passes={} iters={} {:?}", rel(&cells(&o), &reference), h.leaves, h.links, h.elements, h.refinements, o.result.metrics.iterations, t.elapsed());
        }
    }
}
