//! The address a `wavrad serve` child process listens on, read from the first line it prints
//! ("wavrad listening; web page at http://127.0.0.1:PORT/"). Shared by the tests and
//! benchmarks that start real server processes.

use std::io::{BufRead, BufReader};
use std::process::Child;

/// The base URL (`http://127.0.0.1:PORT`, no trailing slash) of a server started with
/// `--addr 127.0.0.1:0` and `stdout` piped.
pub fn base_url(child: &mut Child) -> String {
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout piped"))
        .read_line(&mut line)
        .expect("the server's first line");
    let url = line
        .trim()
        .rsplit(' ')
        .next()
        .unwrap_or_default()
        .trim_end_matches('/')
        .to_string();
    assert!(url.starts_with("http://127.0.0.1:"), "{line}");
    url
}
