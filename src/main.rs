//! The `wavrad` command: `serve` (the HTTP service), `render DOC --out DIR` (one job without a
//! server), `validate DOC` and `import MODEL` (a model as a job document).

use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use wavrad::server::Config;

#[derive(Parser)]
#[command(name = "wavrad", version, about = "Wavelet radiosity render service")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve the HTTP API and the web page.
    Serve(Box<Config>),
    /// Solve one job document and write DIR/result.json, the images and (3d) scene.glb.
    Render {
        /// The job document (JSON).
        doc: PathBuf,
        /// Where to write result.json, image.png, sparsity.png, coefficients.png, surfaces/ and
        /// (3d) scene.glb.
        #[arg(long)]
        out: PathBuf,
    },
    /// Check a job document against the limits of `render` (the library's, more generous than
    /// a server's defaults): prints every error as `PATH: message`; exit 2 when invalid.
    Validate { doc: PathBuf },
    /// Turn a model (Wavefront OBJ with its MTL, glTF 2.0 or GLB) into a job document, written
    /// to standard output; warnings go to standard error. The files the model refers to
    /// (`mtllib`, a glTF's buffers and images) are read beside it. Exit 2 when the model is
    /// broken (the message says where: the line of an OBJ or MTL, the JSON path in a glTF).
    Import { model: PathBuf },
}

fn main() -> ExitCode {
    let filter = tracing_subscriber::EnvFilter::try_from_env("WAVRAD_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,tower_http=warn"));
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    // One JSON object per line with WAVRAD_LOG_FORMAT=json (for log collectors).
    if std::env::var("WAVRAD_LOG_FORMAT").is_ok_and(|f| f == "json") {
        logs.json().init();
    } else {
        logs.with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
            .init();
    }
    match Cli::parse().command {
        Command::Serve(config) => serve(*config),
        Command::Render { doc, out } => render(&doc, &out),
        Command::Validate { doc } => validate(&doc),
        Command::Import { model } => import(&model),
    }
}

fn serve(config: Config) -> ExitCode {
    if let Err(e) = config.check() {
        eprintln!("wavrad: {e}");
        return ExitCode::from(2);
    }
    // before the runtime's and the solver's threads start allocating
    wavrad::server::queue::tune_malloc();
    let runtime = tokio::runtime::Runtime::new().expect("a tokio runtime");
    let result = runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(config.addr).await?;
        let addr = listener.local_addr()?;
        println!("wavrad listening; web page at http://{addr}/");
        wavrad::server::run(listener, config, shutdown_signal()).await
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("wavrad: {e}");
            ExitCode::from(1)
        }
    }
}

async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
}

fn read(doc: &Path) -> Result<String, ExitCode> {
    std::fs::read_to_string(doc).map_err(|e| {
        eprintln!("wavrad: cannot read {}: {e}", doc.display());
        ExitCode::from(1)
    })
}

fn parse(text: &str) -> Result<wavrad::scene::Job, ExitCode> {
    wavrad::scene::parse_document(text, &wavrad::scene::Limits::default()).map_err(|errors| {
        for e in &errors.0 {
            println!("{e}");
        }
        ExitCode::from(2)
    })
}

fn validate(doc: &Path) -> ExitCode {
    let run = || -> Result<(), ExitCode> {
        parse(&read(doc)?)?;
        println!("{}: valid", doc.display());
        Ok(())
    };
    run().err().unwrap_or(ExitCode::SUCCESS)
}

fn render(doc: &Path, out: &Path) -> ExitCode {
    let run = || -> Result<(), ExitCode> {
        let job = parse(&read(doc)?)?;
        let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).map_err(|e| {
            eprintln!("wavrad: the solve failed: {e}");
            ExitCode::from(3)
        })?;
        let images = wavrad::render::render_all(&job, &outcome);
        let json = serde_json::to_vec_pretty(&outcome.result).expect("a result serialises");
        let io = |e: std::io::Error| {
            eprintln!("wavrad: cannot write to {}: {e}", out.display());
            ExitCode::from(1)
        };
        std::fs::create_dir_all(out.join("surfaces")).map_err(io)?;
        std::fs::write(out.join("result.json"), json).map_err(io)?;
        for (name, bytes) in images.files() {
            // A surface name is one file name: separators become '_'.
            let name = match name.strip_prefix("surfaces/") {
                Some(file) => format!("surfaces/{}", file.replace(['/', '\\'], "_")),
                None => name,
            };
            std::fs::write(out.join(&name), bytes).map_err(io)?;
        }
        println!("wrote {}", out.display());
        Ok(())
    };
    run().err().unwrap_or(ExitCode::SUCCESS)
}

fn import(path: &Path) -> ExitCode {
    use wavrad::import::{Format, Model};
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("wavrad: cannot read {}: {e}", path.display());
            return ExitCode::from(1);
        }
    };
    let file = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let format = if bytes.starts_with(b"glTF") {
        Some(Format::Glb)
    } else {
        Format::from_file_name(&file)
    };
    let Some(format) = format else {
        eprintln!("wavrad: {file}: not a model (.obj, .gltf or .glb)");
        return ExitCode::from(2);
    };
    let folder = path.parent().unwrap_or(Path::new(""));
    // the files the model names, beside it (a URI's %20 is tried as a space by the importer)
    let files = |name: &str| std::fs::read(folder.join(name)).ok();
    let model = Model {
        file: &file,
        format,
        bytes: &bytes,
    };
    match wavrad::import::import(model, &files, &wavrad::scene::Limits::default()) {
        Ok(imported) => {
            for w in &imported.warnings {
                eprintln!("wavrad: warning: {w}");
            }
            let text =
                serde_json::to_string_pretty(&imported.document).expect("a document serialises");
            println!("{text}");
            eprintln!(
                "wavrad: {file}: {} surfaces, {} triangles",
                imported.surfaces, imported.triangles
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("wavrad: {e}");
            ExitCode::from(2)
        }
    }
}
