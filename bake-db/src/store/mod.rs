//! The redb file: schema version, meshes by content hash, artefacts by bake key with their
//! metadata, per-scene references (for `gc`) and lineage (for incremental re-bake).
//!
//! Every write is one redb transaction, so a process killed at any moment leaves the file as of
//! the last commit: completed batches survive, the batch in flight is lost.

use crate::key::Key;
use redb::{Database, ReadableDatabase, ReadableTable, ReadableTableMetadata, TableDefinition};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

mod merge;

pub use merge::MergeStats;

/// Bumped when a table's meaning or an artefact layout changes incompatibly.
pub const SCHEMA_VERSION: u32 = 1;

const META: TableDefinition<&str, &[u8]> = TableDefinition::new("meta");
/// Mesh content hash → (vertices, triangles) as two little-endian u32.
const MESHES: TableDefinition<&[u8], &[u8]> = TableDefinition::new("meshes");
/// Bake key → artefact bytes (POD).
const ARTEFACTS: TableDefinition<&[u8], &[u8]> = TableDefinition::new("artefacts");
/// Bake key → metadata JSON (kind, parameters, algorithm version, seconds, bytes, checksum).
const INFO: TableDefinition<&[u8], &str> = TableDefinition::new("info");
/// Scene name → the keys its last plan used (concatenated 32-byte keys).
const SCENES: TableDefinition<&str, &[u8]> = TableDefinition::new("scenes");
/// Scene name → artefacts made outside its bake plan (radiance-cache records): pairs of the
/// artefact's key and the geometry (`plan::Snapshot::hash`) it was made for, 64 bytes each.
/// Older files lack the table: readers treat it as empty, the first writer creates it.
const EXTRAS: TableDefinition<&str, &[u8]> = TableDefinition::new("extras");
/// Lineage slot → the last artefact baked there and what it was baked against.
const LINEAGE: TableDefinition<&[u8], &[u8]> = TableDefinition::new("lineage");
/// Name → a memo: partial results a baker keeps between runs to speed re-bakes up (e.g. BSPVT
/// tile subtrees, occluder BVHs); never part of an artefact, so losing one costs only time.
/// Each value checks itself when loaded. Older files lack the table: readers treat it as empty.
/// The table keeps its schema-1 name, "caches".
const MEMOS: TableDefinition<&str, &[u8]> = TableDefinition::new("caches");

/// redb's page cache, at most (its default, 1 GiB, made a 2 GB database's bake hold 1.9 GB:
/// a bake writes each artefact once and reads little back, so pages kept past the B-trees'
/// inner nodes save nothing).
const CACHE_BYTES: usize = 256 << 20;

/// A memo's name and bytes.
pub type Memo = (String, Vec<u8>);

/// What can go wrong with the database file.
#[derive(Debug, thiserror::Error)]
pub enum DbError {
    /// Another process has the file open.
    #[error("{0}: the bake database is in use by another process (close it, or pass --db OTHER.redb)")]
    Locked(PathBuf),
    /// The file is not a redb database or is damaged beyond repair.
    #[error("{path}: not a readable bake database ({detail}); delete it to start over, or pass --db OTHER.redb")]
    Corrupted {
        /// The file.
        path: PathBuf,
        /// What redb said.
        detail: String,
    },
    /// The file was written by an incompatible version of kage.
    #[error("{path}: bake database schema version {found}, this kage reads version {expected}; delete it to re-bake")]
    Schema {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        expected: u32,
    },
    /// The run was cancelled; everything committed before stays in the database.
    #[error("bake cancelled ({done} vertices committed)")]
    Cancelled {
        /// Vertices whose results reached the database.
        done: usize,
    },
    /// An I/O or storage failure while running.
    #[error("{path}: {detail}")]
    Storage {
        /// The file.
        path: PathBuf,
        /// What failed.
        detail: String,
    },
}

/// Result alias.
pub type Result<T> = std::result::Result<T, DbError>;

/// Metadata stored beside an artefact.
#[derive(Clone, Debug, PartialEq)]
pub struct Info {
    /// `bspvt` or `prt`.
    pub kind: String,
    /// Parameters and algorithm version, as text.
    pub params: String,
    /// Seconds the bake took.
    pub seconds: f64,
    /// Vertices baked from scratch (0 for warm re-bakes and non-vertex artefacts).
    pub vertices: usize,
    /// blake3 of the artefact bytes.
    pub checksum: [u8; 32],
}

impl Info {
    /// The metadata recorded as `json` beside an artefact (`None` when unreadable).
    pub fn parse(json: &str) -> Option<Info> {
        let v: serde_json::Value = serde_json::from_str(json).ok()?;
        Some(Info {
            kind: v.get("kind")?.as_str()?.to_string(),
            params: v.get("params")?.as_str()?.to_string(),
            seconds: v.get("seconds")?.as_f64()?,
            vertices: v.get("vertices")?.as_u64()? as usize,
            checksum: checksum_of(json)?,
        })
    }
}

/// An open bake database.
pub struct Store {
    db: Handle,
    path: PathBuf,
}

/// The redb handle, closed inside a panic guard: redb commits its allocator state when a
/// database is dropped, and asserts on some damaged pages there.
struct Handle(Option<Db>);

/// A database opened for writing, or read-only (many processes may read one file at once).
enum Db {
    Writable(Database),
    ReadOnly(redb::ReadOnlyDatabase),
}

impl Handle {
    fn db(&self) -> &Db {
        self.0.as_ref().expect("open until dropped")
    }

    fn begin_read(&self) -> std::result::Result<redb::ReadTransaction, redb::TransactionError> {
        match self.db() {
            Db::Writable(d) => d.begin_read(),
            Db::ReadOnly(d) => d.begin_read(),
        }
    }

    /// The writable database; `None` when opened read-only.
    fn writable(&mut self) -> Option<&mut Database> {
        match self.0.as_mut() {
            Some(Db::Writable(d)) => Some(d),
            _ => None,
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        if let Some(db) = self.0.take() {
            // Nothing more to report: every result was committed, or its error returned, earlier.
            let _ = kage_engine::error::contain(move || drop(db));
        }
    }
}

/// The result of [`Store::check`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CheckReport {
    /// Artefacts whose bytes match their checksum.
    pub ok: usize,
    /// Keys of artefacts whose bytes do not match, or that lack metadata.
    pub bad: Vec<Key>,
    /// False when redb had to repair the file.
    pub clean: bool,
}

/// Runs `f` on the database at `path`, turning a panic inside the storage library (it asserts
/// on some damaged pages) into an error that names the file: damaged bytes never crash kage.
fn contained<T>(path: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    kage_engine::error::contain(f).unwrap_or_else(|what| {
        Err(DbError::Corrupted {
            path: path.to_path_buf(),
            detail: format!("a damaged page ({what}); run `kage db check`"),
        })
    })
}

impl Store {
    /// Opens (creating if needed, with its parent folder) the database at `path`.
    ///
    /// A new database is made whole under a temporary name and then linked into place, so a
    /// process killed while creating it never leaves a half-written file at `path`.
    pub fn open(path: &Path) -> Result<Self> {
        refuse_symlink(path)?;
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(|e| storage(path, e))?;
        if !path.exists() {
            Self::create(path, dir)?;
        }
        let db = contained(path, || {
            Database::builder().set_cache_size(CACHE_BYTES).create(path).map_err(|e| match e {
                redb::DatabaseError::DatabaseAlreadyOpen => DbError::Locked(path.to_path_buf()),
                other => DbError::Corrupted { path: path.to_path_buf(), detail: other.to_string() },
            })
        })?;
        let store = Self { db: Handle(Some(Db::Writable(db))), path: path.to_path_buf() };
        store.init()?;
        sweep_partials(path, dir);
        Ok(store)
    }

    /// Opens the existing database at `path` for reading only: any number of processes may
    /// (e.g. every shard of a bake reading its base), none while one has it open for writing.
    /// Every write through it is an error.
    pub fn open_read_only(path: &Path) -> Result<Self> {
        refuse_symlink(path)?;
        if !path.is_file() {
            return Err(DbError::Storage { path: path.to_path_buf(), detail: "no bake database here".into() });
        }
        let db = contained(path, || {
            Database::builder().set_cache_size(CACHE_BYTES).open_read_only(path).map_err(|e| match e {
                redb::DatabaseError::DatabaseAlreadyOpen => DbError::Locked(path.to_path_buf()),
                other => DbError::Corrupted { path: path.to_path_buf(), detail: other.to_string() },
            })
        })?;
        let store = Self { db: Handle(Some(Db::ReadOnly(db))), path: path.to_path_buf() };
        match store.read(|t| Ok(t.open_table(META)?.get("schema_version")?.map(|v| v.value().to_vec())))? {
            Some(v) if v == SCHEMA_VERSION.to_le_bytes() => Ok(store),
            found => Err(DbError::Schema {
                path: path.to_path_buf(),
                found: found.and_then(|v| v.try_into().ok()).map_or(0, u32::from_le_bytes),
                expected: SCHEMA_VERSION,
            }),
        }
    }

    /// Writes an initialised database beside `path` and links it there unless another process
    /// got there first (then its file is the one used).
    fn create(path: &Path, dir: &Path) -> Result<()> {
        let io = |e: std::io::Error| storage(path, e);
        let partial =
            tempfile::Builder::new().prefix(&partial_prefix(path)).suffix(".partial").tempfile_in(dir).map_err(io)?;
        let redb = |e: redb::DatabaseError| storage(path, redb::Error::from(e));
        let backend = redb::backends::FileBackend::new(partial.reopen().map_err(io)?).map_err(redb)?;
        let db = Database::builder().create_with_backend(backend).map_err(redb)?;
        Self { db: Handle(Some(Db::Writable(db))), path: path.to_path_buf() }.init()?;
        match partial.persist_noclobber(path) {
            Ok(_) => Ok(()),
            Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
            // A filesystem without hard links or no-replace renames: a plain rename, atomic too.
            Err(e) => e.file.persist(path).map(drop).map_err(|e| io(e.error)),
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// True when opened with [`Store::open_read_only`].
    pub fn read_only(&self) -> bool {
        matches!(self.db.0, Some(Db::ReadOnly(_)))
    }

    /// Creates the tables and the schema version, or checks the version.
    fn init(&self) -> Result<()> {
        let found = self.read(|t| {
            let meta = t.open_table(META)?;
            Ok(meta.get("schema_version")?.map(|v| u32::from_le_bytes(v.value().try_into().unwrap_or([0; 4]))))
        });
        match found {
            Ok(Some(v)) if v == SCHEMA_VERSION => Ok(()),
            Ok(Some(found)) => Err(DbError::Schema { path: self.path.clone(), found, expected: SCHEMA_VERSION }),
            _ => self.write(|t| {
                t.open_table(META)?.insert("schema_version", SCHEMA_VERSION.to_le_bytes().as_slice())?;
                for table in [MESHES, ARTEFACTS, LINEAGE] {
                    t.open_table(table)?;
                }
                t.open_table(INFO)?;
                t.open_table(SCENES)?;
                Ok(())
            }),
        }
    }

    fn read<T>(&self, f: impl FnOnce(&redb::ReadTransaction) -> std::result::Result<T, redb::Error>) -> Result<T> {
        self.contained(|| {
            let t = self.db.begin_read().map_err(|e| storage(&self.path, e))?;
            f(&t).map_err(|e| storage(&self.path, e))
        })
    }

    fn write(&self, f: impl FnOnce(&redb::WriteTransaction) -> std::result::Result<(), redb::Error>) -> Result<()> {
        self.contained(|| {
            let Some(Db::Writable(db)) = self.db.0.as_ref() else {
                return Err(DbError::Storage { path: self.path.clone(), detail: "opened read-only".into() });
            };
            let t = db.begin_write().map_err(|e| storage(&self.path, e))?;
            f(&t).map_err(|e| storage(&self.path, e))?;
            t.commit().map_err(|e| storage(&self.path, e))
        })
    }

    fn contained<T>(&self, f: impl FnOnce() -> Result<T>) -> Result<T> {
        contained(&self.path, f)
    }

    /// Which of `keys` have an artefact.
    pub fn contains_all(&self, keys: &[Key]) -> Result<Vec<bool>> {
        self.read(|t| {
            let a = t.open_table(ARTEFACTS)?;
            keys.iter().map(|k| Ok(a.get(k.as_bytes().as_slice())?.is_some())).collect()
        })
    }

    /// Whether each slot has a lineage entry (without reading the entries).
    pub fn has_lineage(&self, slots: &[Key]) -> Result<Vec<bool>> {
        self.read(|t| {
            let l = t.open_table(LINEAGE)?;
            slots.iter().map(|k| Ok(l.get(k.as_bytes().as_slice())?.is_some())).collect()
        })
    }

    /// The artefact of `key`, copied once into aligned memory as `T`s.
    pub fn get<T: bytemuck::Pod>(&self, key: &Key) -> Result<Option<Vec<T>>> {
        self.with_artefacts(std::slice::from_ref(key), |found| Ok(found[0].map(bytemuck::pod_collect_to_vec)))
    }

    /// Calls `f` with the artefacts of `keys` in order (`None` where missing), all read in one
    /// transaction and borrowed from the database's pages: loading copies each byte once, into
    /// whatever `f` builds.
    pub fn with_artefacts<R>(&self, keys: &[Key], f: impl FnOnce(&[Option<&[u8]>]) -> Result<R>) -> Result<R> {
        self.contained(|| {
            let t = self.db.begin_read().map_err(|e| storage(&self.path, e))?;
            let table = t.open_table(ARTEFACTS).map_err(|e| storage(&self.path, e))?;
            let guards = keys
                .iter()
                .map(|k| table.get(k.as_bytes().as_slice()))
                .collect::<std::result::Result<Vec<_>, _>>()
                .map_err(|e| storage(&self.path, e))?;
            let found: Vec<Option<&[u8]>> = guards.iter().map(|g| g.as_ref().map(|g| g.value())).collect();
            f(&found)
        })
    }

    /// [`Store::with_artefacts`], each artefact checked against the checksum recorded with it
    /// while `f` runs (on the other cores, on the borrowed bytes): `f`'s result when every
    /// artefact is intact, else the damaged keys (and `f`'s result, built from them, dropped),
    /// so that loads never shade garbage.
    pub fn with_checked_artefacts<R: Send>(
        &self,
        keys: &[Key],
        f: impl FnOnce(&[Option<&[u8]>]) -> Result<R> + Send,
    ) -> Result<std::result::Result<R, Vec<Key>>> {
        use rayon::prelude::*;
        self.contained(|| {
            let t = self.db.begin_read().map_err(|e| storage(&self.path, e))?;
            let table = t.open_table(ARTEFACTS).map_err(|e| storage(&self.path, e))?;
            let info = t.open_table(INFO).map_err(|e| storage(&self.path, e))?;
            let fetch = |k: &Key| -> std::result::Result<_, redb::StorageError> {
                let sum = info.get(k.as_bytes().as_slice())?.and_then(|i| checksum_of(i.value()));
                Ok((table.get(k.as_bytes().as_slice())?, sum))
            };
            let rows = keys.iter().map(fetch).collect::<std::result::Result<Vec<_>, _>>();
            let rows = rows.map_err(|e| storage(&self.path, e))?;
            let found: Vec<Option<&[u8]>> = rows.iter().map(|(g, _)| g.as_ref().map(|g| g.value())).collect();
            let damaged = || -> Vec<Key> {
                let intact = |(v, (_, sum)): (&Option<&[u8]>, &(_, Option<[u8; 32]>))| {
                    v.is_none_or(|v| *sum == Some(*blake3::hash(v).as_bytes()))
                };
                let ok: Vec<bool> = found.par_iter().zip(&rows).map(intact).collect();
                keys.iter().zip(ok).filter(|(_, ok)| !ok).map(|(k, _)| *k).collect()
            };
            let (damaged, built) = rayon::join(damaged, || f(&found));
            if damaged.is_empty() { built.map(Ok) } else { Ok(Err(damaged)) }
        })
    }

    /// Writes a batch of artefacts (with metadata) and lineage entries in one transaction.
    pub fn put_batch(&self, artefacts: &[(Key, Vec<u8>, Info)], lineage: &[(Key, Vec<u8>)]) -> Result<()> {
        self.write(|t| {
            let mut a = t.open_table(ARTEFACTS)?;
            let mut i = t.open_table(INFO)?;
            for (key, bytes, info) in artefacts {
                a.insert(key.as_bytes().as_slice(), bytes.as_slice())?;
                i.insert(key.as_bytes().as_slice(), info_json(info, bytes.len()).as_str())?;
            }
            let mut l = t.open_table(LINEAGE)?;
            for (slot, value) in lineage {
                l.insert(slot.as_bytes().as_slice(), value.as_slice())?;
            }
            Ok(())
        })
    }

    /// The lineage entry of `slot`.
    pub fn lineage(&self, slot: &Key) -> Result<Option<Vec<u8>>> {
        self.read(|t| Ok(t.open_table(LINEAGE)?.get(slot.as_bytes().as_slice())?.map(|v| v.value().to_vec())))
    }

    /// Whether a memo is stored under `name` (without reading it).
    pub fn has_memo(&self, name: &str) -> Result<bool> {
        self.read(|t| match t.open_table(MEMOS) {
            Ok(c) => Ok(c.get(name)?.is_some()),
            Err(redb::TableError::TableDoesNotExist(_)) => Ok(false),
            Err(e) => Err(e.into()),
        })
    }

    /// The memo stored under `name`.
    pub fn memo(&self, name: &str) -> Result<Option<Vec<u8>>> {
        self.read(|t| match t.open_table(MEMOS) {
            Ok(c) => Ok(c.get(name)?.map(|v| v.value().to_vec())),
            Err(redb::TableError::TableDoesNotExist(_)) => Ok(None),
            Err(e) => Err(e.into()),
        })
    }

    /// The stored memos' names and sizes in bytes, by name.
    pub fn memos(&self) -> Result<Vec<(String, usize)>> {
        self.read(|t| match t.open_table(MEMOS) {
            Ok(c) => c
                .iter()?
                .map(|item| item.map(|(k, v)| (k.value().to_string(), v.value().len())).map_err(Into::into))
                .collect(),
            Err(redb::TableError::TableDoesNotExist(_)) => Ok(Vec::new()),
            Err(e) => Err(e.into()),
        })
    }

    /// Stores (replaces) memos by name, in one transaction; writes nothing when there are none.
    pub fn put_memos(&self, memos: &[Memo]) -> Result<()> {
        if memos.is_empty() {
            return Ok(());
        }
        self.write(|t| {
            let mut table = t.open_table(MEMOS)?;
            for (name, bytes) in memos {
                table.insert(name.as_str(), bytes.as_slice())?;
            }
            Ok(())
        })
    }

    /// Records meshes (content hash → vertex and triangle counts); writes only when some are new
    /// (a commit is durable, and a fully cached run should cost no disk flush).
    pub fn put_meshes(&self, meshes: &[([u8; 32], u32, u32)]) -> Result<()> {
        let known = self.read(|t| {
            let m = t.open_table(MESHES)?;
            meshes
                .iter()
                .map(|(hash, ..)| Ok(m.get(hash.as_slice())?.is_some()))
                .collect::<std::result::Result<Vec<_>, redb::Error>>()
        })?;
        if known.iter().all(|&k| k) {
            return Ok(());
        }
        self.write(|t| {
            let mut m = t.open_table(MESHES)?;
            for (hash, v, tris) in meshes {
                let mut value = v.to_le_bytes().to_vec();
                value.extend_from_slice(&tris.to_le_bytes());
                m.insert(hash.as_slice(), value.as_slice())?;
            }
            Ok(())
        })
    }

    /// A metadata value (e.g. PRT parameters chosen from a budget).
    pub fn meta(&self, name: &str) -> Result<Option<Vec<u8>>> {
        self.read(|t| Ok(t.open_table(META)?.get(name)?.map(|v| v.value().to_vec())))
    }

    /// Sets a metadata value.
    pub fn put_meta(&self, name: &str, value: &[u8]) -> Result<()> {
        self.write(|t| {
            t.open_table(META)?.insert(name, value)?;
            Ok(())
        })
    }

    /// Records the keys a scene's plan uses for its current `geometry` (what `gc` keeps), and
    /// forgets the scene's extra artefacts made for other geometry. Writes only on a change.
    pub fn put_scene(&self, scene: &str, keys: &[Key], geometry: &Key) -> Result<()> {
        let bytes: Vec<u8> = keys.iter().flat_map(|k| *k.as_bytes()).collect();
        let unchanged = self.read(|t| {
            let same_keys = t.open_table(SCENES)?.get(scene)?.is_some_and(|v| v.value() == bytes.as_slice());
            let same_extras = match t.open_table(EXTRAS) {
                Ok(extras) => extras.get(scene)?.is_none_or(|v| kept_extras(v.value(), geometry) == v.value()),
                Err(redb::TableError::TableDoesNotExist(_)) => true,
                Err(e) => return Err(e.into()),
            };
            Ok(same_keys && same_extras)
        })?;
        if unchanged {
            return Ok(());
        }
        self.write(|t| {
            t.open_table(SCENES)?.insert(scene, bytes.as_slice())?;
            let mut extras = t.open_table(EXTRAS)?;
            let kept = extras.get(scene)?.map(|v| kept_extras(v.value(), geometry)).unwrap_or_default();
            extras.insert(scene, kept.as_slice())?;
            Ok(())
        })
    }

    /// Adds an artefact made outside the bake plan for the scene's `geometry` (kept by `gc`
    /// until a bake records other geometry for the scene).
    pub fn add_extra(&self, scene: &str, key: &Key, geometry: &Key) -> Result<()> {
        let entry = [*key.as_bytes(), *geometry.as_bytes()].concat();
        // Read and write in one transaction: a bake's `put_scene` cannot slip in between.
        self.write(|t| {
            let mut extras = t.open_table(EXTRAS)?;
            let mut bytes = extras.get(scene)?.map(|v| v.value().to_vec()).unwrap_or_default();
            if !bytes.chunks_exact(64).any(|e| e == entry.as_slice()) {
                bytes.extend_from_slice(&entry);
                extras.insert(scene, bytes.as_slice())?;
            }
            Ok(())
        })
    }

    /// Every artefact's key, metadata and size, by key (unreadable metadata reads as empty).
    pub fn artefacts(&self) -> Result<Vec<(Key, Info, usize)>> {
        self.read(|t| {
            let (a, i) = (t.open_table(ARTEFACTS)?, t.open_table(INFO)?);
            let mut out = Vec::new();
            for row in a.iter()? {
                let (k, v) = row?;
                let info = i.get(k.value())?.and_then(|j| Info::parse(j.value()));
                let empty =
                    Info { kind: String::new(), params: String::new(), seconds: 0.0, vertices: 0, checksum: [0; 32] };
                out.push((Key::from_slice(k.value()), info.unwrap_or(empty), v.value().len()));
            }
            Ok(out)
        })
    }

    /// Counts of (artefacts, their bytes, meshes, scenes).
    pub fn counts(&self) -> Result<(u64, u64, u64, u64)> {
        self.read(|t| {
            let a = t.open_table(ARTEFACTS)?;
            let mut bytes = 0u64;
            for item in a.iter()? {
                bytes += item?.1.value().len() as u64;
            }
            Ok((a.len()?, bytes, t.open_table(MESHES)?.len()?, t.open_table(SCENES)?.len()?))
        })
    }

    /// Verifies redb's own integrity (repairing what it can) and every artefact's checksum.
    pub fn check(&mut self) -> Result<CheckReport> {
        let clean = match self.db.writable() {
            Some(db) => db
                .check_integrity()
                .map_err(|e| DbError::Corrupted { path: self.path.clone(), detail: e.to_string() })?,
            None => true,
        };
        let bad = self.read(|t| {
            let (a, i) = (t.open_table(ARTEFACTS)?, t.open_table(INFO)?);
            let mut out = Vec::new();
            let mut ok = 0usize;
            for item in a.iter()? {
                let (k, v) = item?;
                let key = Key::from_slice(k.value());
                let good = i
                    .get(k.value())?
                    .is_some_and(|info| checksum_of(info.value()) == Some(*blake3::hash(v.value()).as_bytes()));
                if good { ok += 1 } else { out.push(key) }
            }
            Ok((ok, out))
        })?;
        Ok(CheckReport { ok: bad.0, bad: bad.1, clean })
    }

    /// Drops artefacts that no recorded scene references (its plan's keys or its extras), and
    /// every cache (the next bake rebuilds what it needs); returns how many artefacts went.
    /// Lineage pointing at a dropped artefact stays: its slot's next bake is cold.
    pub fn gc(&self) -> Result<usize> {
        let keep: HashSet<[u8; 32]> = self.read(|t| {
            let s = t.open_table(SCENES)?;
            let mut keep = HashSet::new();
            for item in s.iter()? {
                for k in item?.1.value().chunks_exact(32) {
                    keep.insert(k.try_into().expect("32-byte chunk"));
                }
            }
            match t.open_table(EXTRAS) {
                Ok(extras) => {
                    for item in extras.iter()? {
                        for e in item?.1.value().chunks_exact(64) {
                            keep.insert(e[..32].try_into().expect("32-byte key"));
                        }
                    }
                }
                Err(redb::TableError::TableDoesNotExist(_)) => {}
                Err(e) => return Err(e.into()),
            }
            Ok(keep)
        })?;
        let doomed: Vec<Vec<u8>> = self.read(|t| {
            let a = t.open_table(ARTEFACTS)?;
            let mut out = Vec::new();
            for item in a.iter()? {
                let k = item?.0.value().to_vec();
                if !keep.contains(k.as_slice()) {
                    out.push(k);
                }
            }
            Ok(out)
        })?;
        self.write(|t| {
            let (mut a, mut i) = (t.open_table(ARTEFACTS)?, t.open_table(INFO)?);
            for k in &doomed {
                a.remove(k.as_slice())?;
                i.remove(k.as_slice())?;
            }
            t.delete_table(MEMOS)?;
            Ok(())
        })?;
        Ok(doomed.len())
    }
}

/// How the temporary files that [`Store::create`] makes for `path` start.
fn partial_prefix(path: &Path) -> String {
    format!(".{}.", path.file_name().map_or("bake".into(), |n| n.to_string_lossy()))
}

/// Removes temporary files left by processes killed while creating `path`. Creating one takes
/// milliseconds, so any older than a minute is abandoned.
fn sweep_partials(path: &Path, dir: &Path) {
    let prefix = partial_prefix(path);
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let stale = entry.metadata().and_then(|m| m.modified()).ok().and_then(|t| t.elapsed().ok());
        if name.starts_with(&prefix) && name.ends_with(".partial") && stale.is_some_and(|age| age.as_secs() > 60) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// A database path that is a symbolic link is refused: the file is updated in place, and a
/// link (dangling ones included) would have kage create or change a file somewhere else.
fn refuse_symlink(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(DbError::Storage {
            path: path.to_path_buf(),
            detail: "is a symbolic link; a bake database is opened only at its real path (pass that with --db)".into(),
        }),
        _ => Ok(()),
    }
}

fn storage(path: &Path, e: impl Into<redb::Error>) -> DbError {
    DbError::Storage { path: path.to_path_buf(), detail: e.into().to_string() }
}

/// The (key, geometry) entries of a scene's extras that were made for `geometry`.
fn kept_extras(entries: &[u8], geometry: &Key) -> Vec<u8> {
    entries.chunks_exact(64).filter(|e| &e[32..] == geometry.as_bytes()).flatten().copied().collect()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn info_json(info: &Info, len: usize) -> String {
    serde_json::json!({
        "kind": info.kind,
        "params": info.params,
        "seconds": info.seconds,
        "vertices": info.vertices,
        "bytes": len,
        "checksum": hex(&info.checksum),
    })
    .to_string()
}

fn checksum_of(json: &str) -> Option<[u8; 32]> {
    let v: serde_json::Value = serde_json::from_str(json).ok()?;
    let h = v.get("checksum")?.as_str()?;
    let bytes: Vec<u8> =
        (0..h.len()).step_by(2).map(|i| u8::from_str_radix(h.get(i..i + 2)?, 16).ok()).collect::<Option<_>>()?;
    bytes.try_into().ok()
}
