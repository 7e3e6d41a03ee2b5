//! The web page in real headless Chromium, driven over WebDriver (Debian's chromedriver):
//! load `/`, submit `flatland-parallel`, wait for the image, compare the shown numbers with the
//! result JSON (integers exactly) and the job id with the file posted as written; show a
//! validation error next to its input; show the geometry warnings of crossing segments; show
//! image.png in the 3D view's place for a 3d scene without WebGL; fit a phone-width screen.
//! Then, with WebGL through SwiftShader, solve the Cornell box and see it in the 3D view: the
//! green wall on the left, the red on the right, and a drag turns it.
//! Without chromium and chromedriver the test fails (`scripts/test` installs them).

mod common;

use common::*;
use fantoccini::{ClientBuilder, Locator};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn find(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for name in names {
        for dir in std::env::split_paths(&path).chain([
            PathBuf::from("/usr/bin"),
            PathBuf::from("/usr/lib/chromium"),
        ]) {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

async fn until<F, Fut>(what: &str, limit: Duration, mut check: F)
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = bool>,
{
    let t = Instant::now();
    while !check().await {
        assert!(t.elapsed() < limit, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// A server on a free port and Chromium driven over WebDriver, started with `args` besides
/// the usual ones; a failure when chromedriver or chromium is missing.
struct Session {
    client: fantoccini::Client,
    base: String,
    stop: tokio::sync::oneshot::Sender<()>,
    server: tokio::task::JoinHandle<std::io::Result<()>>,
    _driver: Driver,
    _dir: tempfile::TempDir,
}

async fn open(args: &[&str]) -> Session {
    let (Some(chromedriver), Some(chromium)) = (
        find(&["chromedriver"]),
        find(&["chromium", "chromium-browser", "google-chrome"]),
    ) else {
        panic!(
            "the browser test needs chromium and chromedriver: run scripts/test, which installs \
             them, or apt-get install chromium chromium-driver"
        );
    };

    let dir = tempfile::tempdir().unwrap();
    let state = state(config(dir.path()));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(wavrad::server::run_with(
        listener,
        state.clone(),
        async move {
            let _ = stopped.await;
        },
        Duration::from_millis(200),
    ));

    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let driver = Driver(
        Command::new(&chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut all = vec![
        "--headless",
        "--no-sandbox",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-dev-shm-usage",
        "--window-size=1200,900",
    ];
    all.extend_from_slice(args);
    let caps: serde_json::Map<String, Value> = serde_json::from_value(json!({
        "goog:chromeOptions": { "binary": chromium, "args": all }
    }))
    .unwrap();
    let webdriver = format!("http://127.0.0.1:{port}");
    let t = Instant::now();
    let client = loop {
        match ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(caps.clone())
            .connect(&webdriver)
            .await
        {
            Ok(c) => break c,
            Err(e) => {
                assert!(
                    t.elapsed() < Duration::from_secs(30),
                    "chromedriver did not start: {e}"
                );
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    };
    Session {
        client,
        base,
        stop,
        server,
        _driver: driver,
        _dir: dir,
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_solves_flatland_parallel_in_chromium() {
    let Session {
        client,
        base,
        stop,
        server,
        _driver,
        _dir,
    } = open(&["--disable-gpu", "--disable-3d-apis"]).await;

    client.goto(&format!("{base}/")).await.unwrap();
    let select = client
        .wait()
        .at_most(Duration::from_secs(20))
        .for_element(Locator::Css(
            "#scene-select option[value='flatland-parallel']",
        ))
        .await
        .unwrap();
    drop(select);
    client
        .find(Locator::Id("scene-select"))
        .await
        .unwrap()
        .select_by_value("flatland-parallel")
        .await
        .unwrap();
    until(
        "the scene in the text area",
        Duration::from_secs(20),
        || async {
            let v = client
                .execute("return document.getElementById('doc').value", vec![])
                .await
                .unwrap();
            v.as_str().unwrap_or("").contains("parallel segments")
        },
    )
    .await;
    assert_eq!(
        client
            .find(Locator::Id("resolution"))
            .await
            .unwrap()
            .prop("value")
            .await
            .unwrap()
            .as_deref(),
        Some("16")
    );

    // A validation error is shown with its path next to its input.
    client
        .execute("document.getElementById('order').value = '99'", vec![])
        .await
        .unwrap();
    client
        .find(Locator::Id("submit"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let error = client
        .wait()
        .at_most(Duration::from_secs(20))
        .for_element(Locator::Css("#errors li[data-path='/solver/order']"))
        .await
        .unwrap();
    assert!(error.text().await.unwrap().contains("/solver/order"));
    let beside = client
        .find(Locator::Id("order-error"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(beside.contains("/solver/order"), "{beside}");
    client
        .execute("document.getElementById('order').value = '1'", vec![])
        .await
        .unwrap();

    // Submit, follow the progress, see the image and the numbers.
    client
        .find(Locator::Id("submit"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let cell = client
        .wait()
        .at_most(Duration::from_secs(60))
        .for_element(Locator::Id("mean-1-0"))
        .await
        .unwrap();
    let shown: f64 = cell.text().await.unwrap().parse().unwrap();
    until("the image to load", Duration::from_secs(30), || async {
        let v = client
            .execute(
                "const i = document.getElementById('image'); return i.complete && i.naturalWidth > 0 && i.src.endsWith('image.png')",
                vec![],
            )
            .await
            .unwrap();
        v.as_bool() == Some(true)
    })
    .await;
    assert_eq!(
        client
            .find(Locator::Id("state"))
            .await
            .unwrap()
            .text()
            .await
            .unwrap(),
        "succeeded"
    );
    let id = client
        .find(Locator::Id("job-id"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let result: Value = reqwest::get(format!("{base}/api/v1/jobs/{id}/result"))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(result["surfaces"][1]["name"], "top");
    let expected = result["surfaces"][1]["mean"][0].as_f64().unwrap();
    assert!(
        ((shown - expected) / expected).abs() < 1e-5,
        "page shows {shown}, result has {expected}"
    );
    let iterations = client
        .find(Locator::Id("metric-iterations"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert_eq!(iterations, result["metrics"]["iterations"].to_string());
    // integers exactly as in the result, not rounded to six digits
    for (id, value) in [
        ("metric-basis-size", &result["coefficients"]["basis_size"]),
        (
            "metric-matrix-entries",
            &result["coefficients"]["matrix_entries"],
        ),
        (
            "metric-kept-entries",
            &result["coefficients"]["kept_entries"],
        ),
    ] {
        assert!(value.is_u64(), "{id}: {value}");
        let shown = client
            .find(Locator::Id(id))
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        assert_eq!(shown, value.to_string(), "{id}");
    }
    // the page sent the document as written (`"emission": 1.0` stays 1.0): the same job as
    // the file posted as it is
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/flatland-parallel.json"
    ))
    .unwrap();
    assert!(
        text.contains("1.0"),
        "the example writes a number with a fraction"
    );
    let posted: Value = reqwest::Client::new()
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "application/json")
        .body(text)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(posted["id"].as_str(), Some(id.as_str()));
    // no geometry warning for this scene
    let hidden = client
        .execute(
            "return document.getElementById('warnings-panel').hidden",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(hidden.as_bool(), Some(true));
    // the icon the page names is served
    let icon = client
        .execute(
            "return document.querySelector(\"link[rel='icon']\").href",
            vec![],
        )
        .await
        .unwrap();
    for url in [
        icon.as_str().unwrap().to_string(),
        format!("{base}/favicon.ico"),
    ] {
        let r = reqwest::get(&url).await.unwrap();
        assert_eq!(r.status(), 200, "{url}");
        assert_eq!(r.headers()["content-type"], "image/svg+xml", "{url}");
    }

    if let Ok(dir) = std::env::var("WAVRAD_SCREENSHOT_DIR") {
        client.set_window_size(1200, 1600).await.unwrap();
        let png = client.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(dir).join("desktop.png"), png).unwrap();
    }

    // Crossing segments: solved, and the warning is shown with the surfaces' paths.
    let crossing = json!({"scene": {"kind": "flatland", "name": "crossing", "surfaces": [
        {"name": "a", "segment": [[0, 0], [1, 1]], "reflectance": 0.5, "emission": 1},
        {"name": "b", "segment": [[0, 1], [1, 0]], "reflectance": 0.5}]}});
    client
        .execute(
            "document.getElementById('doc').value = arguments[0]",
            vec![Value::String(crossing.to_string())],
        )
        .await
        .unwrap();
    client
        .find(Locator::Id("submit"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let warning = client
        .wait()
        .at_most(Duration::from_secs(60))
        .for_element(Locator::Css("#warnings li"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        warning.contains("/scene/surfaces/0") && warning.contains("/scene/surfaces/1"),
        "{warning}"
    );
    assert!(warning.contains("cross"), "{warning}");
    let hidden = client
        .execute(
            "return document.getElementById('warnings-panel').hidden",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(hidden.as_bool(), Some(false));

    // A 3d scene without WebGL (--disable-3d-apis): the 3D view shows image.png instead.
    let plates = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/plates-3d.json"
    ))
    .unwrap();
    client
        .execute(
            "document.getElementById('doc').value = arguments[0]",
            vec![Value::String(plates)],
        )
        .await
        .unwrap();
    client
        .find(Locator::Id("submit"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    until("the image instead of the 3D view", Duration::from_secs(60), || async {
        let v = client
            .execute(
                "const i = document.getElementById('view3d-fallback'); return !!i && i.complete && i.naturalWidth > 0 && i.src.endsWith('image.png') && document.getElementById('view3d').dataset.state === 'image'",
                vec![],
            )
            .await
            .unwrap();
        v.as_bool() == Some(true)
    })
    .await;
    let note = client
        .find(Locator::Id("view3d-note"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(note.contains("no WebGL"), "{note}");

    // Phone width: nothing wider than the screen.
    client.set_window_size(390, 844).await.unwrap();
    let fits = client
        .execute(
            "return document.documentElement.scrollWidth <= window.innerWidth + 1",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        fits.as_bool(),
        Some(true),
        "the page scrolls sideways at phone width"
    );
    if let Ok(dir) = std::env::var("WAVRAD_SCREENSHOT_DIR") {
        let png = client.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(dir).join("phone.png"), png).unwrap();
    }

    client.close().await.unwrap();
    stop.send(()).unwrap();
    server.await.unwrap().unwrap();
}

/// The mean colour of two vertical bands of the 3D view's canvas (the left and right 4–18 % of
/// its width, the middle 40 % of its height) and a checksum of all its pixels.
const READ_CANVAS: &str = r#"
const c = document.getElementById('view3d-canvas');
const w = c.width, h = c.height;
const copy = document.createElement('canvas'); copy.width = w; copy.height = h;
const g = copy.getContext('2d'); g.drawImage(c, 0, 0);
const d = g.getImageData(0, 0, w, h).data;
const band = (a, b) => {
  const m = [0, 0, 0]; let n = 0;
  for (let y = Math.floor(h * 0.3); y < h * 0.7; y++)
    for (let x = Math.floor(w * a); x < w * b; x++) {
      const i = 4 * (y * w + x); m[0] += d[i]; m[1] += d[i + 1]; m[2] += d[i + 2]; n++;
    }
  return m.map((v) => v / n);
};
let sum = 0, lit = 0;
for (let i = 0; i < d.length; i += 4) { sum = (sum * 31 + d[i] + 7 * d[i + 1] + 13 * d[i + 2]) % 1000000007; if (d[i] + d[i + 1] + d[i + 2] > 30) lit++; }
return { left: band(0.04, 0.18), right: band(0.82, 0.96), sum, lit: lit / (w * h), width: w, height: h };
"#;

#[tokio::test(flavor = "multi_thread")]
async fn the_page_opens_the_obj_cornell_box_solves_it_and_turns_it_in_3d() {
    // WebGL without a GPU: SwiftShader through ANGLE
    let Session {
        client,
        base,
        stop,
        server,
        _driver,
        _dir,
    } = open(&["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]).await;
    client.goto(&format!("{base}/")).await.unwrap();
    client
        .wait()
        .at_most(Duration::from_secs(20))
        .for_element(Locator::Css("#scene-select option[value='cornell-box']"))
        .await
        .unwrap();
    // the Cornell box as a model, OBJ with its MTL, opened from the file input: the page
    // imports it and puts the document into the text area
    let fixtures = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/import");
    client
        .find(Locator::Id("model-file"))
        .await
        .unwrap()
        .send_keys(&format!(
            "{fixtures}/cornell-box.obj\n{fixtures}/cornell-box.mtl"
        ))
        .await
        .unwrap();
    until(
        "the imported model in the text area",
        Duration::from_secs(20),
        || async {
            let v = client
                .execute("return document.getElementById('doc').value", vec![])
                .await
                .unwrap();
            let doc: Value = serde_json::from_str(v.as_str().unwrap_or("")).unwrap_or(Value::Null);
            doc["scene"]["surfaces"]
                .as_array()
                .is_some_and(|s| s.iter().any(|s| s.get("mesh").is_some()))
        },
    )
    .await;
    // then, as a user would in the editor, the camera of the hand-written box and order 0
    // (an edit, with its input event, of a field that a control also shows)
    let camera = scene("cornell-box")["output"]["camera"].clone();
    client
        .execute(
            "const d = JSON.parse(document.getElementById('doc').value); \
             d.output = Object.assign(d.output || {}, {camera: arguments[0]}); \
             d.solver = Object.assign(d.solver || {}, {order: 0}); \
             const doc = document.getElementById('doc'); \
             doc.value = JSON.stringify(d, null, 2); \
             doc.dispatchEvent(new Event('input'));",
            vec![camera],
        )
        .await
        .unwrap();
    client
        .find(Locator::Id("submit"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    // what was typed is what is sent (the page sends the text area as it stands after Solve):
    // the order control followed the edit instead of writing its older value over it
    let sent = client
        .execute(
            "return [JSON.parse(document.getElementById('doc').value).solver.order, \
                     document.getElementById('order').value]",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(sent, json!([0, "0"]));
    until("the 3D view", Duration::from_secs(180), || async {
        let v = client
            .execute(
                "return document.getElementById('view3d').dataset.state || ''",
                vec![],
            )
            .await
            .unwrap();
        !v.as_str().unwrap_or("").is_empty()
    })
    .await;
    let state = client
        .execute(
            "return [document.getElementById('view3d').dataset.state, document.getElementById('view3d-note').textContent]",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        state[0], "3d",
        "the 3D view fell back to the image: {state}"
    );
    // the scene.glb that the view shows is the job's
    let href = client
        .execute("return document.getElementById('model-link').href", vec![])
        .await
        .unwrap();
    let glb = reqwest::get(href.as_str().unwrap()).await.unwrap();
    assert_eq!(glb.status(), 200);
    assert_eq!(glb.headers()["content-type"], "model/gltf-binary");

    let before = client.execute(READ_CANVAS, vec![]).await.unwrap();
    eprintln!("the 3D view from image.png's camera: {before}");
    let rgb = |v: &Value| -> [f64; 3] { std::array::from_fn(|c| v[c].as_f64().unwrap()) };
    let (left, right) = (rgb(&before["left"]), rgb(&before["right"]));
    // green wall on the left, red wall on the right, as in image.png
    assert!(
        left[1] > 1.5 * left[0] && left[1] > 1.5 * left[2] && left[1] > 60.0,
        "the left of the view is not the green wall: {left:?}"
    );
    assert!(
        right[0] > 1.5 * right[1] && right[0] > 1.5 * right[2] && right[0] > 60.0,
        "the right of the view is not the red wall: {right:?}"
    );
    assert!(before["lit"].as_f64().unwrap() > 0.8, "{before}");
    if let Ok(dir) = std::env::var("WAVRAD_SCREENSHOT_DIR") {
        let png = client.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(dir).join("view3d.png"), png).unwrap();
    }

    // Orbit: drag 60 pixels across the canvas with the mouse (about 60° around the box); the
    // picture changes
    use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
    let canvas = client.find(Locator::Id("view3d-canvas")).await.unwrap();
    let drag = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: canvas,
            duration: None,
            x: 0,
            y: 0,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::MoveBy {
            duration: Some(Duration::from_millis(300)),
            x: 60,
            y: 10,
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    client.perform_actions(drag).await.unwrap();
    let after = client.execute(READ_CANVAS, vec![]).await.unwrap();
    eprintln!("after a drag: {after}");
    assert_ne!(before["sum"], after["sum"], "the picture did not change");
    let (left2, right2) = (rgb(&after["left"]), rgb(&after["right"]));
    let moved = (0..3)
        .map(|c| (left2[c] - left[c]).abs() + (right2[c] - right[c]).abs())
        .sum::<f64>();
    assert!(moved > 20.0, "the walls did not move: {left2:?} {right2:?}");
    if let Ok(dir) = std::env::var("WAVRAD_SCREENSHOT_DIR") {
        let png = client.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(dir).join("view3d-turned.png"), png).unwrap();
    }

    client.close().await.unwrap();
    stop.send(()).unwrap();
    server.await.unwrap().unwrap();
}
