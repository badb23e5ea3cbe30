//! Long calls on their own thread: this thread releases the GIL and polls for Ctrl-C.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use pyo3::prelude::*;

/// Why [`run_interruptible`] has no result.
pub(crate) enum WorkerError {
    /// A signal arrived (Ctrl-C): the error Python raised for it. The worker was told to stop
    /// and has finished.
    Signal(PyErr),
    /// The thread could not be started.
    Spawn(std::io::Error),
    /// The thread ended without sending a result.
    Lost,
}

/// Runs `work` on a thread named `name`. Every 50 ms this thread takes the GIL back briefly to
/// check for signals; on one it sets the stop flag handed to `work`, waits for the worker and
/// returns [`WorkerError::Signal`].
pub(crate) fn run_interruptible<T: Send + 'static>(py: Python<'_>, name: &str, work: impl FnOnce(&Arc<AtomicBool>) -> T + Send + 'static) -> Result<T, WorkerError> {
    run_interruptible_ticking(py, name, work, |_| Ok(()))
}

/// [`run_interruptible`], calling `tick` with the GIL every 50 ms while the worker runs (e.g. to
/// report progress to a Python callback). An error from `tick` stops the worker like a signal
/// and is returned as [`WorkerError::Signal`].
pub(crate) fn run_interruptible_ticking<T: Send + 'static>(
    py: Python<'_>,
    name: &str,
    work: impl FnOnce(&Arc<AtomicBool>) -> T + Send + 'static,
    mut tick: impl FnMut(Python<'_>) -> PyResult<()>,
) -> Result<T, WorkerError> {
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let worker = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let _ = tx.send(work(&stop));
            })
            .map_err(WorkerError::Spawn)?
    };
    let mut interrupted: Option<PyErr> = None;
    let mut rx = rx;
    let result = loop {
        // the receiver is Send but not Sync: move it in and out of the GIL-free closure
        let (back, received) = py.detach(move || {
            let r = rx.recv_timeout(Duration::from_millis(50));
            (rx, r)
        });
        rx = back;
        match received {
            Ok(result) => break result,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if interrupted.is_none() {
                    if let Err(e) = py.check_signals().and_then(|()| tick(py)) {
                        stop.store(true, Ordering::Relaxed);
                        interrupted = Some(e);
                    }
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                let _ = worker.join();
                return Err(WorkerError::Lost);
            }
        }
    };
    let _ = worker.join();
    match interrupted {
        Some(e) => Err(WorkerError::Signal(e)),
        None => Ok(result),
    }
}
