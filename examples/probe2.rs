use serde_json::json;
use wavrad::{
    job,
    progress::Silent,
    scene::{parse_value, Limits},
};
fn main() {
    let walls = [
        [[0.0, 0.0], [1.0, 0.0]],
        [[1.0, 0.0], [1.0, 1.0]],
        [[1.0, 1.0], [0.0, 1.0]],
        [[0.0, 1.0], [0.0, 0.0]],
    ];
    let surfaces: Vec<serde_json::Value> = walls.iter().enumerate().map(|(i, s)| json!({"name": format!("s{i}"), "segment": s, "reflectance": 0.5, "emission": 1.0})).collect();
    for eps in [0.9, 0.1, 1e-2, 1e-3] {
        for res in [1, 2, 4, 64] {
            let doc = json!({"scene": {"kind": "flatland", "surfaces": surfaces}, "solver": {"method": "hierarchical", "order": 0, "resolution": res, "epsilon": eps, "tolerance": 1e-12}});
            let o = job::run(&parse_value(&doc, &Limits::default()).unwrap(), &Silent).unwrap();
            let h = o.result.hierarchical.unwrap();
            println!(
                "eps={eps} res={res}: mean {:?} leaves={} links={} passes={}",
                o.result.surfaces[0].mean[0], h.leaves, h.links, h.refinements
            );
        }
    }
}
