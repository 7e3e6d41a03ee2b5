//! The web page in real headless Chromium, driven over WebDriver (Debian's chromedriver):
//! load `/`, submit `flatland-parallel`, wait for the image, compare the shown numbers with the
//! result JSON (integers exactly) and the job id with the file posted as written; show a
//! validation error next to its input; show the geometry warnings of crossing segments; fit a
//! phone-width screen.
//! Without chromedriver the test fails when `CI` is set and is skipped otherwise.

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

#[tokio::test(flavor = "multi_thread")]
async fn the_page_solves_flatland_parallel_in_chromium() {
    let (Some(chromedriver), Some(chromium)) = (
        find(&["chromedriver"]),
        find(&["chromium", "chromium-browser", "google-chrome"]),
    ) else {
        if std::env::var_os("CI").is_some() {
            panic!(
                "chromedriver and chromium are required under CI (apt-get install chromium chromium-driver)"
            );
        }
        eprintln!("skipped: chromedriver or chromium not installed");
        return;
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
    let _driver = Driver(
        Command::new(&chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let caps: serde_json::Map<String, Value> = serde_json::from_value(json!({
        "goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                     "--disable-background-networking", "--disable-dev-shm-usage", "--window-size=1200,900"]
        }
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
