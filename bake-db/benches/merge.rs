//! Merge throughput (`kage db merge`): a shard database of 128 MB of artefacts — 512 chunks
//! of 256 KB, a large BSPVT chunk's size at 128² faces — merged into an empty database, every
//! artefact's checksum and version checked. Each iteration merges into a fresh file (untimed
//! set-up); the shard is opened afresh, so redb's page cache starts cold as in a new process.

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use kage_bake_db::Store;
use kage_bake_db::key::KeyHasher;
use kage_bake_db::store::Info;

const CHUNKS: u64 = 512;
const CHUNK_BYTES: usize = 256 << 10;

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("kage-merge-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch folder");
    let shard = dir.join("shard.redb");
    {
        let store = Store::open(&shard).expect("a scratch database");
        for batch in 0..CHUNKS / 64 {
            let artefacts: Vec<_> = (batch * 64..(batch + 1) * 64)
                .map(|n| {
                    let key = KeyHasher::new("bench").u64("chunk", n).finish();
                    let bytes: Vec<u8> = (0..CHUNK_BYTES).map(|i| ((i as u64 * 2654435761) ^ n) as u8).collect();
                    let info = Info {
                        kind: "bspvt".into(),
                        params: format!(
                            "128² faces, ε 2, lights anywhere, algorithm {}, format 1",
                            kage_engine::bspvt::ALGORITHM_VERSION
                        ),
                        seconds: 1.0,
                        vertices: 256,
                        checksum: *blake3::hash(&bytes).as_bytes(),
                    };
                    (key, bytes, info)
                })
                .collect();
            store.put_batch(&artefacts, &[]).expect("a write");
        }
    }
    let mut g = c.benchmark_group("merge");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(CHUNKS * CHUNK_BYTES as u64));
    let mut n = 0;
    g.bench_function("shard_of_128_mb", |b| {
        b.iter_batched(
            || {
                n += 1;
                let out = dir.join(format!("out-{n}.redb"));
                (Store::open(&out).expect("a target"), Store::open_read_only(&shard).expect("the shard"), out)
            },
            |(out, input, path)| {
                let stats = out.merge_from(&input).expect("a merge");
                assert_eq!(stats.added as u64, CHUNKS);
                drop(out);
                let _ = std::fs::remove_file(path);
            },
            BatchSize::PerIteration,
        )
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
