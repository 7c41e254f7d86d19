//! The threads calibration runs independent work on: [`par_jobs`] splits jobs (one per
//! recording) into contiguous runs of about equal rows, [`pool_map`] hands whole fits to
//! threads as they free up, and work started on a pool thread stays on it. A job's
//! result is the same as run alone, so no output depends on the number of threads.

/// Rows below which one evaluation is not worth a second thread.
const PAR_MIN_ROWS: usize = 20_000;

thread_local! {
    /// Set on [`pool_map`]'s threads: what they run runs on one thread.
    static IN_POOL: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// `f` of every item, on up to `available_parallelism` threads taking the next item as
/// they finish one (each item on one thread, its own work not split further); results
/// in the items' order.
pub(super) fn pool_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len());
    if threads < 2 || IN_POOL.with(|p| p.get()) {
        return items.iter().map(f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let (f, next) = (&f, &next);
    let mut out: Vec<(usize, R)> = std::thread::scope(|sc| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                sc.spawn(move || {
                    IN_POOL.with(|p| p.set(true));
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            break;
                        };
                        mine.push((i, f(item)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a calibration thread panicked"))
            .collect()
    });
    out.sort_by_key(|r| r.0);
    out.into_iter().map(|r| r.1).collect()
}

/// Runs `f` on every job, weighed by `rows`, in contiguous runs of about equal weight on
/// up to `available_parallelism` threads (one thread under [`PAR_MIN_ROWS`]).
pub(super) fn par_jobs<J: Send, R: Send>(
    jobs: &mut [J],
    rows: impl Fn(&J) -> usize,
    f: impl Fn(&mut J) -> R + Sync,
) -> Vec<R> {
    let total: usize = jobs.iter().map(&rows).sum();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len());
    if threads < 2 || total < PAR_MIN_ROWS || IN_POOL.with(|p| p.get()) {
        return jobs.iter_mut().map(&f).collect();
    }
    // Contiguous chunks of about total / threads each.
    let mut bounds = vec![0];
    let mut acc = 0;
    for (i, j) in jobs.iter().enumerate() {
        acc += rows(j);
        if bounds.len() < threads && acc * threads >= total * bounds.len() {
            bounds.push(i + 1);
        }
    }
    if bounds.last() != Some(&jobs.len()) {
        bounds.push(jobs.len());
    }
    let mut chunks = Vec::new();
    let mut rest = jobs;
    for w in bounds.windows(2) {
        let (a, b) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
        chunks.push(a);
        rest = b;
    }
    let f = &f;
    std::thread::scope(|sc| {
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|c| sc.spawn(move || c.iter_mut().map(f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a calibration thread panicked"))
            .collect()
    })
}

/// Threads worth splitting `items` pieces of work over `rows` rows each into: up to
/// `available_parallelism`, one under [`PAR_MIN_ROWS`] rows or on a pool thread.
pub(super) fn threads_for(rows: usize, items: usize) -> usize {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items);
    if rows < PAR_MIN_ROWS || IN_POOL.with(|p| p.get()) {
        1
    } else {
        threads.max(1)
    }
}

/// Deals `items` round-robin over one thread per state of `states`, each thread running
/// `f(its state, item)` on its items in turn (as a pool thread: what they start stays on
/// them). For work whose state cannot be shared between threads (a problem's caches).
pub(super) fn deal<S: Send, T: Send>(states: Vec<S>, items: Vec<T>, f: impl Fn(&mut S, T) + Sync) {
    let n = states.len().max(1);
    let mut hands: Vec<Vec<T>> = (0..n).map(|_| Vec::new()).collect();
    for (k, item) in items.into_iter().enumerate() {
        hands[k % n].push(item);
    }
    let f = &f;
    std::thread::scope(|sc| {
        for (mut state, hand) in states.into_iter().zip(hands) {
            sc.spawn(move || {
                IN_POOL.with(|p| p.set(true));
                for item in hand {
                    f(&mut state, item);
                }
            });
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Results come back in the items' order, each the item's own (integers: exact),
    /// however the threads took them, and work started on a pool thread stays on it.
    #[test]
    fn pool_map_keeps_the_items_order_and_values() {
        let items: Vec<u64> = (0..1000).collect();
        let sq = pool_map(&items, |&i| i * i);
        assert_eq!(sq, items.iter().map(|i| i * i).collect::<Vec<_>>());
        // With two threads or more, the items run on pool threads, and a pool_map they
        // start runs on the same thread (it sees the flag); with one, all run here.
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let nested = pool_map(&items[..4], |&i| {
            let on_pool = IN_POOL.with(|p| p.get());
            let inner = pool_map(&items[..3], |&j| (j, IN_POOL.with(|p| p.get())));
            (i, on_pool, inner)
        });
        for (k, (i, on_pool, inner)) in nested.iter().enumerate() {
            assert_eq!(*i, k as u64);
            assert_eq!(*on_pool, threads >= 2);
            assert_eq!(inner, &[(0, *on_pool), (1, *on_pool), (2, *on_pool)]);
        }
    }

    /// Each job is run once, in place, and its result lands at its index, whether the
    /// jobs stay on one thread (under PAR_MIN_ROWS rows) or are split into runs.
    #[test]
    fn par_jobs_runs_each_job_once_in_order() {
        for rows in [10, PAR_MIN_ROWS] {
            let mut jobs: Vec<(usize, u64)> = (0..37).map(|i| (rows, i)).collect();
            let out = par_jobs(
                &mut jobs,
                |j| j.0,
                |j| {
                    j.1 += 1000;
                    j.1 * 2
                },
            );
            let want: Vec<u64> = (0..37).map(|i| (i + 1000) * 2).collect();
            assert_eq!(out, want);
            assert!(jobs.iter().enumerate().all(|(i, j)| j.1 == i as u64 + 1000));
        }
    }

    /// Every item is dealt once, to the thread of one state; the states see their own
    /// items only (integers: exact).
    #[test]
    fn deal_hands_every_item_to_one_state() {
        let sums = std::sync::Mutex::new(vec![0u64; 3]);
        let states: Vec<usize> = (0..3).collect();
        deal(states, (1..=100u64).collect(), |k, item| {
            sums.lock().unwrap()[*k] += item;
        });
        let sums = sums.into_inner().unwrap();
        assert_eq!(sums.iter().sum::<u64>(), 5050);
        // Round robin: state k gets k+1, k+4, ... (34, 33 and 33 items).
        assert_eq!(
            sums,
            vec![
                (0..34).map(|i| 1 + 3 * i).sum::<u64>(),
                (0..33).map(|i| 2 + 3 * i).sum(),
                (0..33).map(|i| 3 + 3 * i).sum()
            ]
        );
    }
}
