//! An IO that shows what passes through it to a [`Watch`]: the one `AsyncRead` and
//! `AsyncWrite` forwarding under every connection, shared by the stall guard
//! ([`super::stall`]) and the connection's head watch ([`super::connections`]).

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// Which write-side call a result came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WriteOp {
    /// `poll_write` or `poll_write_vectored`.
    Write,
    /// `poll_flush`.
    Flush,
    /// `poll_shutdown`.
    Shutdown,
}

/// What a [`Watched`] IO tells its watcher.
pub(crate) trait Watch {
    /// `n` (> 0) bytes were read; by default nothing is noted.
    fn read(&mut self, n: usize) {
        let _ = n;
    }

    /// The write-side call `op` returned `poll`; the caller gets what this returns, so a watcher
    /// may note the result or replace it (a pending write failed at a deadline).
    fn wrote<R>(
        &mut self,
        cx: &mut Context<'_>,
        op: WriteOp,
        poll: Poll<io::Result<R>>,
    ) -> Poll<io::Result<R>>;
}

/// `io` with every read and write shown to `watch`.
#[derive(Debug)]
pub(crate) struct Watched<T, W> {
    io: T,
    watch: W,
}

impl<T, W> Watched<T, W> {
    /// Watches `io` with `watch`.
    pub(crate) fn new(io: T, watch: W) -> Self {
        Self { io, watch }
    }
}

impl<T: AsyncRead + Unpin, W: Watch + Unpin> AsyncRead for Watched<T, W> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = &mut *self;
        let before = buf.filled().len();
        let poll = Pin::new(&mut this.io).poll_read(cx, buf);
        let n = buf.filled().len() - before;
        if n > 0 {
            this.watch.read(n);
        }
        poll
    }
}

impl<T: AsyncWrite + Unpin, W: Watch + Unpin> AsyncWrite for Watched<T, W> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        let poll = Pin::new(&mut this.io).poll_write(cx, buf);
        this.watch.wrote(cx, WriteOp::Write, poll)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        let poll = Pin::new(&mut this.io).poll_write_vectored(cx, bufs);
        this.watch.wrote(cx, WriteOp::Write, poll)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        let poll = Pin::new(&mut this.io).poll_flush(cx);
        this.watch.wrote(cx, WriteOp::Flush, poll)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        let poll = Pin::new(&mut this.io).poll_shutdown(cx);
        this.watch.wrote(cx, WriteOp::Shutdown, poll)
    }
}
