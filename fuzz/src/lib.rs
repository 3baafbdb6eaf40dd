//! Helpers shared by the fuzz targets.

/// Splits a fuzz input into chunks: `[n, len_1 .. len_n, stream..]`. The first byte says how many
/// of the next bytes are chunk lengths (`n % 16`); the stream after them is cut into pieces of
/// those lengths (0 is allowed: `decode` is then called again with nothing new), and what is left
/// is the last piece. Returns the pieces and the whole stream.
///
/// The fuzzer thus chooses the split points itself, and mutating a length byte moves a split
/// without touching the stream.
pub fn split_input(data: &[u8]) -> (Vec<&[u8]>, &[u8]) {
    let Some((&n, rest)) = data.split_first() else {
        return (Vec::new(), &[]);
    };
    let n = usize::from(n % 16).min(rest.len());
    let (lens, stream) = rest.split_at(n);
    let mut chunks = Vec::with_capacity(n + 1);
    let mut left = stream;
    for &len in lens {
        let (piece, after) = left.split_at(usize::from(len).min(left.len()));
        chunks.push(piece);
        left = after;
    }
    chunks.push(left);
    (chunks, stream)
}

/// The largest single allocation a target may make. Every decoder here documents a bound far below
/// it (one frame, one line, one read); a length read from the wire that reached an allocation would
/// ask for more. libFuzzer's own `-malloc_limit_mb` needs a sanitizer's malloc hooks, and
/// `-rss_limit_mb` misses a large allocation that is never touched (`reserve`), so the targets run
/// under this allocator, which aborts (a crash libFuzzer records) on anything bigger.
pub const MAX_ALLOCATION: usize = 1 << 20;

struct BoundedAllocator;

// SAFETY: forwards to the system allocator unchanged; only refuses (aborts on) oversized requests.
unsafe impl std::alloc::GlobalAlloc for BoundedAllocator {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        check(layout.size());
        // SAFETY: same layout contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        check(layout.size());
        // SAFETY: same layout contract as the caller's.
        unsafe { std::alloc::System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: `ptr` came from `System` with this layout.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        check(new_size);
        // SAFETY: `ptr` came from `System` with this layout.
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

fn check(size: usize) {
    // While a panic is reported, the backtrace printer may allocate more; the crash is already
    // being recorded, so let it.
    if size > MAX_ALLOCATION && !std::thread::panicking() {
        // No formatting: this must not allocate.
        use std::io::Write;
        let _ = std::io::stderr().write_all(b"fuzz: allocation above MAX_ALLOCATION\n");
        std::process::abort();
    }
}

#[global_allocator]
static ALLOCATOR: BoundedAllocator = BoundedAllocator;
