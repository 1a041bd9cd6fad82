//! The HTTP/1.1 transport, on std's `TcpListener`: one request per connection (every answer says
//! `Connection: close`), everything bounded.
//!
//! Written here rather than taken from a crate because the bounds are the point: `tiny_http`
//! (tried first) allocates a buffer of the client's claimed `Content-Length` to skip an unread
//! body, so one request claiming 100 GB aborted the whole server. Here the request head is at
//! most [`MAX_HEAD`] bytes, a body over the limit is refused (413) before any of it is read,
//! sockets have read and write timeouts (a client that stalls cannot hold a worker), and
//! accepted connections wait in a bounded queue (when it is full, 503 at once).

use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Largest request line plus headers.
pub const MAX_HEAD: usize = 16 << 10;
/// Accepted connections waiting for a worker.
pub const ACCEPT_QUEUE: usize = 64;
/// How long a client may take to send its request, or to take our answer.
pub const IO_TIMEOUT: Duration = Duration::from_secs(30);

/// A parsed request with its whole body.
pub struct Request {
    pub method: String,
    /// Path and query, as sent.
    pub target: String,
    /// The headers the server reads (`host`, `origin`, `content-type`), names lowercased.
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Request {
    /// The value of header `name` (lowercase), if sent.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// What the handler answers.
pub struct Response {
    pub status: u16,
    pub content_type: &'static str,
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Response {
    pub fn error(status: u16, message: &str) -> Response {
        Response {
            status,
            content_type: "application/json",
            headers: vec![],
            body: serde_json::json!({ "error": message })
                .to_string()
                .into_bytes(),
        }
    }
}

pub fn reason(status: u16) -> &'static str {
    match status {
        100 => "Continue",
        200 => "OK",
        201 => "Created",
        202 => "Accepted",
        400 => "Bad Request",
        404 => "Not Found",
        403 => "Forbidden",
        405 => "Method Not Allowed",
        409 => "Conflict",
        408 => "Request Timeout",
        411 => "Length Required",
        413 => "Payload Too Large",
        415 => "Unsupported Media Type",
        421 => "Misdirected Request",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "Unknown",
    }
}

/// Accepts connections into the bounded queue (the caller's thread runs this loop until the
/// listener fails, e.g. never in practice).
pub fn accept_loop(listener: TcpListener, queue: SyncSender<TcpStream>, stop: Arc<Mutex<bool>>) {
    for stream in listener.incoming() {
        if *stop.lock().unwrap_or_else(|e| e.into_inner()) {
            return;
        }
        let Ok(stream) = stream else { continue };
        let _ = stream.set_read_timeout(Some(IO_TIMEOUT));
        let _ = stream.set_write_timeout(Some(IO_TIMEOUT));
        match queue.try_send(stream) {
            Ok(()) => {}
            Err(TrySendError::Full(mut s)) => {
                // Answered by the acceptor itself: short, and the write times out.
                let _ = s.set_write_timeout(Some(Duration::from_secs(1)));
                write_response(
                    &mut s,
                    &Response::error(503, "the server is busy: too many connections waiting"),
                    false,
                );
                close(s);
            }
            Err(TrySendError::Disconnected(_)) => return,
        }
    }
}

/// A channel of accepted connections.
pub fn queue() -> (SyncSender<TcpStream>, Arc<Mutex<Receiver<TcpStream>>>) {
    let (tx, rx) = mpsc::sync_channel(ACCEPT_QUEUE);
    (tx, Arc::new(Mutex::new(rx)))
}

/// Serve one connection: read the request within the bounds, answer with `handler`'s response.
pub fn serve_connection(
    mut stream: TcpStream,
    max_body: usize,
    handler: impl FnOnce(Request) -> Response,
) {
    let (response, head_only) = match read_request(&mut stream, max_body) {
        // HEAD is answered like GET, without the body (RFC 9110 9.3.2).
        Ok(request) => {
            let head = request.method == "HEAD";
            (handler(request), head)
        }
        Err(response) => (response, false),
    };
    write_response(&mut stream, &response, head_only);
    close(stream);
}

fn read_request(stream: &mut TcpStream, max_body: usize) -> Result<Request, Response> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 4096];
    let head_end = loop {
        // (A head that arrived in one read is measured too, not only one still arriving.)
        if let Some(i) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            if i + 4 > MAX_HEAD {
                return Err(Response::error(431, "request head over 16 KiB"));
            }
            break i;
        }
        if buf.len() > MAX_HEAD {
            return Err(Response::error(431, "request head over 16 KiB"));
        }
        match stream.read(&mut chunk) {
            Ok(0) => return Err(Response::error(400, "connection closed mid-request")),
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            Err(_) => return Err(Response::error(408, "request not received in time")),
        }
    };
    let head = std::str::from_utf8(&buf[..head_end])
        .map_err(|_| Response::error(400, "request head is not text"))?;
    let mut lines = head.split("\r\n");
    let mut first = lines.next().unwrap_or("").split(' ');
    let (method, target, version) = (first.next(), first.next(), first.next());
    let (Some(method), Some(target), Some(version)) = (method, target, version) else {
        return Err(Response::error(400, "malformed request line"));
    };
    if !version.starts_with("HTTP/1.") || !target.starts_with('/') {
        return Err(Response::error(400, "expected METHOD /path HTTP/1.x"));
    }
    let mut length: Option<usize> = None;
    let mut expect_continue = false;
    let mut headers = Vec::new();
    for line in lines {
        let Some((name, value)) = line.split_once(':') else {
            return Err(Response::error(400, "malformed header line"));
        };
        let (name, value) = (name.trim().to_ascii_lowercase(), value.trim());
        match name.as_str() {
            "content-length" => {
                let value: usize = value
                    .parse()
                    .map_err(|_| Response::error(400, "bad Content-Length"))?;
                // RFC 9112 6.3: lengths that differ leave the body's end unknown.
                if length.is_some_and(|l| l != value) {
                    return Err(Response::error(
                        400,
                        "Content-Length given twice, differently",
                    ));
                }
                length = Some(value);
            }
            "transfer-encoding" if !value.eq_ignore_ascii_case("identity") => {
                return Err(Response::error(
                    411,
                    "chunked bodies are not accepted: send Content-Length",
                ));
            }
            "expect" => expect_continue = value.eq_ignore_ascii_case("100-continue"),
            "host" | "origin" | "content-type" => {
                if headers.iter().any(|(n, _)| *n == name) {
                    return Err(Response::error(400, &format!("header {name} given twice")));
                }
                headers.push((name, value.to_string()));
            }
            _ => {}
        }
    }
    let length = length.unwrap_or(0);
    if length > max_body {
        return Err(Response::error(
            413,
            &format!("body of {length} bytes: larger than the {max_body} allowed"),
        ));
    }
    if expect_continue && length > 0 {
        let _ = stream.write_all(b"HTTP/1.1 100 Continue\r\n\r\n");
    }
    let mut body = buf[head_end + 4..].to_vec();
    if body.len() > length {
        body.truncate(length);
    }
    while body.len() < length {
        let want = (length - body.len()).min(chunk.len());
        match stream.read(&mut chunk[..want]) {
            Ok(0) => return Err(Response::error(400, "body shorter than its Content-Length")),
            Ok(n) => body.extend_from_slice(&chunk[..n]),
            Err(_) => return Err(Response::error(408, "body not received in time")),
        }
    }
    Ok(Request {
        method: method.to_string(),
        target: target.to_string(),
        headers,
        body,
    })
}

fn write_response(stream: &mut TcpStream, r: &Response, head_only: bool) {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n",
        r.status,
        reason(r.status),
        r.content_type,
        r.body.len()
    );
    for (k, v) in &r.headers {
        // Header values are ours; refuse line breaks all the same.
        if !k.contains(['\r', '\n']) && !v.contains(['\r', '\n']) {
            head.push_str(&format!("{k}: {v}\r\n"));
        }
    }
    head.push_str("\r\n");
    let body: &[u8] = if head_only { &[] } else { &r.body };
    let _ = stream
        .write_all(head.as_bytes())
        .and_then(|_| stream.write_all(body))
        .and_then(|_| stream.flush());
}

/// Close after answering. Unread request bytes (a refused body) would make the kernel reset the
/// connection, which can destroy the answer before the client reads it: so stop writing, then
/// drain a bounded amount for a bounded time before closing.
fn close(mut stream: TcpStream) {
    let _ = stream.shutdown(Shutdown::Write);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(500)));
    let mut sink = [0u8; 8192];
    let mut drained = 0usize;
    while drained < (4 << 20) {
        match stream.read(&mut sink) {
            Ok(0) | Err(_) => break,
            Ok(n) => drained += n,
        }
    }
}

/// The local address of a listener bound to `addr` (port 0 picks a free one).
pub fn bind(addr: SocketAddr) -> std::io::Result<(TcpListener, SocketAddr)> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    Ok((listener, local))
}
