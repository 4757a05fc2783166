//! A background computation that streams results to the UI thread and stops when dropped. Each
//! runs on a rayon pool of its own: on the global pool the UI thread's parallel shading would
//! queue behind it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};

/// A thread producing `T`s until it is done or the worker is dropped.
pub struct Worker<T> {
    rx: Receiver<T>,
    stop: Arc<AtomicBool>,
}

impl<T: Send + 'static> Worker<T> {
    /// Runs `work(stop, send)` on a new thread; `wake` runs after each result is sent.
    pub fn spawn(
        work: impl FnOnce(&AtomicBool, &dyn Fn(T)) + Send + 'static,
        wake: impl Fn() + Send + 'static,
    ) -> Self {
        let (tx, rx) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let run = move || {
            let send = |t: T| {
                if tx.send(t).is_ok() {
                    wake();
                }
            };
            work(&flag, &send);
        };
        std::thread::spawn(move || match rayon::ThreadPoolBuilder::new().build() {
            Ok(pool) => pool.install(run),
            // Without threads to spare, share the global pool.
            Err(_) => run(),
        });
        Self { rx, stop }
    }

    /// What arrived since the last call.
    pub fn results(&self) -> Vec<T> {
        self.rx.try_iter().collect()
    }
}

impl<T> Drop for Worker<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}
