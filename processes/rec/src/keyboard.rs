//! Replay's keyboard control when stdin is a terminal: space pauses/resumes, `s` steps one
//! message, `q` quits. The terminal is put in non-canonical, no-echo mode (Ctrl-C still sends
//! SIGINT) and restored when the [`Keyboard`] is dropped.

use nix::sys::termios::{
    LocalFlags, SetArg, SpecialCharacterIndices, Termios, tcgetattr, tcsetattr,
};
use std::io::{IsTerminal, Read};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::Duration;

/// A replay command typed by the user.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    TogglePause,
    Step,
    Quit,
}

impl Key {
    fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            b' ' => Some(Self::TogglePause),
            b's' | b'S' => Some(Self::Step),
            b'q' | b'Q' => Some(Self::Quit),
            _ => None,
        }
    }
}

/// Keys read from the terminal on a thread of their own.
pub struct Keyboard {
    keys: Receiver<Key>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
    saved: Termios,
}

impl Keyboard {
    /// Takes over the terminal when stdin is one; `Ok(None)` otherwise.
    pub fn open_if_terminal() -> Result<Option<Self>, String> {
        let stdin = std::io::stdin();
        if !stdin.is_terminal() {
            return Ok(None);
        }
        let saved =
            tcgetattr(&stdin).map_err(|error| format!("reading terminal settings: {error}"))?;
        let mut raw = saved.clone();
        raw.local_flags
            .remove(LocalFlags::ICANON | LocalFlags::ECHO);
        // read() returns after one byte, or after 0.1 s with none: the reader thread can notice
        // `stop` without a signal.
        raw.control_chars[SpecialCharacterIndices::VMIN as usize] = 0;
        raw.control_chars[SpecialCharacterIndices::VTIME as usize] = 1;
        tcsetattr(&stdin, SetArg::TCSANOW, &raw)
            .map_err(|error| format!("setting terminal mode: {error}"))?;
        let (sender, keys) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let reader_stop = stop.clone();
        let reader = std::thread::Builder::new()
            .name("replay-keys".to_owned())
            .spawn(move || {
                let mut stdin = std::io::stdin().lock();
                let mut byte = [0u8; 1];
                while !reader_stop.load(Ordering::Relaxed) {
                    match stdin.read(&mut byte) {
                        Ok(1) => {
                            if let Some(key) = Key::from_byte(byte[0])
                                && sender.send(key).is_err()
                            {
                                break;
                            }
                        }
                        Ok(_) => {}
                        Err(error) if error.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(_) => break,
                    }
                }
            });
        let reader = match reader {
            Ok(handle) => handle,
            Err(error) => {
                let _ = tcsetattr(&stdin, SetArg::TCSANOW, &saved);
                return Err(format!("starting the keyboard thread: {error}"));
            }
        };
        Ok(Some(Self {
            keys,
            stop,
            reader: Some(reader),
            saved,
        }))
    }

    /// The next key within `timeout`, if any.
    pub fn next_key(&self, timeout: Duration) -> Option<Key> {
        match self.keys.recv_timeout(timeout) {
            Ok(key) => Some(key),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => {
                // The terminal went away: behave like a keyboard nobody types on.
                std::thread::sleep(timeout);
                None
            }
        }
    }
}

impl Drop for Keyboard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
        if let Err(error) = tcsetattr(std::io::stdin(), SetArg::TCSANOW, &self.saved) {
            tracing::warn!(%error, "could not restore the terminal settings");
        }
    }
}
