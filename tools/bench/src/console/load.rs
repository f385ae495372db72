//! The load the benchmark puts on the console: push viewers that take every message, and
//! half-open connections (a request head that never ends), renewed as the console closes
//! them.

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use super::live::{Live, connect_from, open_live};

/// Push viewers, each on a thread of its own.
pub struct Viewers {
    stop: Arc<AtomicBool>,
    views: Arc<AtomicU64>,
    threads: Vec<JoinHandle<()>>,
}

impl Viewers {
    /// `count` viewers, each from an address of its own (127.0.1.10 on).
    pub fn open(port: u16, count: usize) -> Result<Self, String> {
        let mut viewers = Self::empty();
        for k in 0..count {
            viewers.add(port, Ipv4Addr::new(127, 0, 1, 10 + (k % 200) as u8))?;
        }
        Ok(viewers)
    }

    /// `count` viewers from `address`.
    pub fn open_from(port: u16, count: usize, address: Ipv4Addr) -> Result<Self, String> {
        let mut viewers = Self::empty();
        for _ in 0..count {
            viewers.add(port, address)?;
        }
        Ok(viewers)
    }

    fn empty() -> Self {
        Self {
            stop: Arc::new(AtomicBool::new(false)),
            views: Arc::new(AtomicU64::new(0)),
            threads: Vec::new(),
        }
    }

    fn add(&mut self, port: u16, address: Ipv4Addr) -> Result<(), String> {
        let session = 10_000 + self.threads.len() as u64;
        let mut client =
            open_live(address, port, session, None).map_err(|e| format!("viewer: {e}"))?;
        let (stop, views) = (self.stop.clone(), self.views.clone());
        let thread = std::thread::Builder::new()
            .name("bench-viewer".to_owned())
            .spawn(move || {
                while !stop.load(Ordering::Acquire) {
                    match client.next(Duration::from_millis(200)) {
                        Ok(Some(Live::View { .. })) => {
                            views.fetch_add(1, Ordering::Relaxed);
                        }
                        Ok(_) => {}
                        Err(error) => {
                            tracing::warn!(%error, "viewer ended");
                            return;
                        }
                    }
                }
            })
            .map_err(|e| format!("viewer thread: {e}"))?;
        self.threads.push(thread);
        Ok(())
    }

    /// Views received by all of them so far.
    pub fn views(&self) -> u64 {
        self.views.load(Ordering::Relaxed)
    }

    /// Closes them (each thread drops its connection).
    pub fn close(self) {
        self.stop.store(true, Ordering::Release);
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

/// Half-open connections held open (spread over addresses, 10 each, so that the console's
/// per-address bound does not refuse them), each renewed once the console has closed it.
pub struct HalfOpen {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

fn open_one(port: u16, index: usize) -> Option<TcpStream> {
    let address = Ipv4Addr::new(127, 0, 3, 1 + (index / 10) as u8);
    let mut stream = connect_from(address, port, None).ok()?;
    stream
        .write_all(b"GET /api/status HTTP/1.1\r\nHost: console\r\n")
        .ok()?;
    stream.set_nonblocking(true).ok()?;
    Some(stream)
}

impl HalfOpen {
    /// Starts holding `count` half-open connections.
    pub fn start(port: u16, count: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("bench-half-open".to_owned())
                .spawn(move || {
                    let mut streams: Vec<Option<TcpStream>> =
                        (0..count).map(|k| open_one(port, k)).collect();
                    while !stop.load(Ordering::Acquire) {
                        for (k, slot) in streams.iter_mut().enumerate() {
                            let closed = match slot {
                                None => true,
                                Some(stream) => {
                                    let mut buffer = [0u8; 256];
                                    match stream.read(&mut buffer) {
                                        // Closed (0 bytes) or answered by the server (a
                                        // timeout's reply before it closes): done either way.
                                        Ok(bytes_read) => {
                                            tracing::trace!(bytes_read, "half-open slot ended");
                                            true
                                        }
                                        Err(error) => {
                                            error.kind() != std::io::ErrorKind::WouldBlock
                                        }
                                    }
                                }
                            };
                            if closed {
                                *slot = open_one(port, k);
                            }
                        }
                        // Not a hot path: the console closes these after seconds.
                        std::thread::sleep(Duration::from_millis(100));
                    }
                })
                .ok()
        };
        Self { stop, thread }
    }

    /// Closes them all.
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
