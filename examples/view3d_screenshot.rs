//! A screenshot of the page's 3D view of a solved model, as a user gets it: open the model
//! files from the page's file input, merge optional settings into the imported document,
//! press Solve, wait for the 3D view and save it as a PNG. It drives headless Chromium over
//! WebDriver (Debian's `chromium` and `chromium-driver`; WebGL through SwiftShader), against a
//! server that is already running:
//!
//! ```text
//! cargo run --release -- serve &
//! cargo run --release --example view3d_screenshot -- http://127.0.0.1:8080 out.png \
//!     '{"solver": {"epsilon": 0.002}}' model.obj model.mtl
//! ```
//!
//! The settings (third argument, `{}` for none) are merged into the document's top-level
//! objects (`solver`, `output`) before it is submitted, written back without indentation (the
//! page sends the text as it stands, and a server takes at most `--max-body-bytes` of it). The README's picture of the 3D view is
//! made this way (its command is in the README).

use fantoccini::{ClientBuilder, Locator};
use serde_json::{json, Value};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [base, out, settings, models @ ..] = args.as_slice() else {
        return Err("usage: view3d_screenshot BASE_URL OUT.png SETTINGS_JSON MODEL_FILE...".into());
    };
    if models.is_empty() {
        return Err("no model file given".into());
    }
    let settings: Value = serde_json::from_str(settings)?;
    let models: Vec<String> = models
        .iter()
        .map(|m| std::fs::canonicalize(m).map(|p| p.display().to_string()))
        .collect::<Result<_, _>>()?;

    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let mut driver = Command::new("chromedriver")
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start chromedriver (apt-get install chromium-driver): {e}"))?;
    let result = shoot(port, base, out, &settings, &models).await;
    let _ = driver.kill();
    let _ = driver.wait();
    result
}

async fn shoot(
    port: u16,
    base: &str,
    out: &str,
    settings: &Value,
    models: &[String],
) -> Result<(), Box<dyn std::error::Error>> {
    let caps: serde_json::Map<String, Value> = serde_json::from_value(json!({
        "goog:chromeOptions": { "args": [
            "--headless", "--no-sandbox", "--no-first-run", "--disable-background-networking",
            "--disable-dev-shm-usage", "--window-size=1200,900",
            "--use-angle=swiftshader", "--enable-unsafe-swiftshader"
        ] }
    }))?;
    let t = Instant::now();
    let client = loop {
        match ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(caps.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
        {
            Ok(c) => break c,
            Err(e) if t.elapsed() > Duration::from_secs(30) => {
                return Err(format!("chromedriver did not start: {e}").into())
            }
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    };
    client.goto(&format!("{base}/")).await?;
    client
        .wait()
        .at_most(Duration::from_secs(20))
        .for_element(Locator::Id("model-file"))
        .await?
        .send_keys(&models.join("\n"))
        .await?;
    wait(
        &client,
        "the imported model",
        60,
        "return document.getElementById('doc').value.includes('\"mesh\"')",
    )
    .await?;
    client
        .execute(
            "const d = JSON.parse(document.getElementById('doc').value); \
             for (const [k, v] of Object.entries(arguments[0])) \
               d[k] = (typeof v === 'object' && !Array.isArray(v)) ? Object.assign(d[k] || {}, v) : v; \
             const doc = document.getElementById('doc'); \
             doc.value = JSON.stringify(d); \
             doc.dispatchEvent(new Event('input'));",
            vec![settings.clone()],
        )
        .await?;
    client.find(Locator::Id("submit")).await?.click().await?;
    // the 3D view, or what the page says went wrong (a refused document, a failed job)
    wait(
        &client,
        "the 3D view",
        3600,
        "return (document.getElementById('view3d').dataset.state || '') !== '' \
           || document.getElementById('errors').children.length > 0 \
           || document.getElementById('doc-error').textContent !== '' \
           || document.getElementById('failure').textContent !== ''",
    )
    .await?;
    let trouble = client
        .execute(
            "return [...document.getElementById('errors').children].map(e => e.textContent) \
               .concat([document.getElementById('doc-error').textContent, \
                        document.getElementById('failure').textContent]) \
               .filter(t => t !== '').join('; ')",
            vec![],
        )
        .await?;
    if let Some(t) = trouble.as_str().filter(|t| !t.is_empty()) {
        return Err(format!("the page says: {t}").into());
    }
    let state = client
        .execute(
            "return document.getElementById('view3d').dataset.state",
            vec![],
        )
        .await?;
    if state != "3d" {
        return Err(format!("the 3D view fell back to the image ({state}): no WebGL?").into());
    }
    // the canvas draws on the next frames
    tokio::time::sleep(Duration::from_secs(2)).await;
    let png = client
        .find(Locator::Id("view3d-canvas"))
        .await?
        .screenshot()
        .await?;
    std::fs::write(out, png)?;
    eprintln!("wrote {out}");
    client.close().await?;
    Ok(())
}

/// Polls the page until `script` returns true, for at most `seconds`.
async fn wait(
    client: &fantoccini::Client,
    what: &str,
    seconds: u64,
    script: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let t = Instant::now();
    while client.execute(script, vec![]).await? != Value::Bool(true) {
        if t.elapsed() > Duration::from_secs(seconds) {
            return Err(format!("timed out waiting for {what}").into());
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    Ok(())
}
