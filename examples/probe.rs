use serde_json::{json, Value};
use wavrad::{
    job,
    progress::Silent,
    scene::{parse_value, Limits},
};
fn main() {
    let name = std::env::args().nth(1).unwrap();
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&name).unwrap()).unwrap();
    for m in [0, 1, 2] {
        for basis in ["scaling", "wavelet"] {
            let mut line = format!("m={m} {basis:8}");
            for top in [64, 256, 1024, 4096, 16384] {
                let mut d = doc.clone();
                d["solver"] = json!({"order": m, "resolution": 64, "basis": basis, "keep": {"top": top}, "tolerance": 1e-12});
                d["output"] = json!({"grid": 16, "reference": {"order": m, "resolution": 128}});
                let j = parse_value(&d, &Limits::default()).unwrap();
                let o = job::run(&j, &Silent).unwrap();
                line += &format!(
                    " N={top}: k={:.1e} b={:.1e} |",
                    o.result.metrics.kernel_relative_error.unwrap(),
                    o.result.metrics.radiosity_relative_error.unwrap()
                );
            }
            println!("{line}");
        }
    }
}
