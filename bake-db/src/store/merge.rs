//! Merging databases (`kage db merge`): shard databases, or any others, into one.
//!
//! Every artefact is checked before it is copied: its checksum against its bytes, its
//! algorithm or layout version against this kage's. A key the target already holds must hold
//! the same bytes — content keys make a difference a bug or a foreign file, named with both
//! paths. Artefacts are copied in transactions of at most [`BATCH_BYTES`]; the small tables
//! (meshes, scenes, extras, lineage, metadata) in one at the end. A merge killed at any moment
//! leaves the target as of its last commit, and merging again completes it: merging is
//! idempotent. The memos, which only save time, are not merged: each baker rebuilds them (BVHs,
//! the subtree memo) as it goes.

use super::{ARTEFACTS, DbError, EXTRAS, INFO, Info, LINEAGE, MESHES, META, Result, SCENES, Store, checksum_of};
use crate::key::Key;
use redb::{ReadableTable, TableDefinition};

/// Bytes of artefacts copied per transaction.
pub const BATCH_BYTES: usize = 64 << 20;

/// What a merge did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MergeStats {
    /// Artefacts copied.
    pub added: usize,
    /// Artefacts the target already held (the same bytes).
    pub present: usize,
    /// Bytes of the artefacts copied.
    pub bytes: u64,
}

impl Store {
    /// Merges every artefact, mesh, scene record, extra, lineage entry and metadata value of
    /// `input` into this database (see the module documentation).
    pub fn merge_from(&self, input: &Store) -> Result<MergeStats> {
        let mut stats = MergeStats::default();
        let keys: Vec<Vec<u8>> =
            input.read(|t| rows(t.open_table(ARTEFACTS)?.iter()?.map(|r| r.map(|(k, _)| k.value().to_vec()))))?;
        let mut next = 0;
        while next < keys.len() {
            let batch = input.read(|t| {
                let (artefacts, info) = (t.open_table(ARTEFACTS)?, t.open_table(INFO)?);
                let (mut batch, mut size) = (Vec::new(), 0);
                while next < keys.len() && size < BATCH_BYTES {
                    let key = &keys[next];
                    let bytes = artefacts.get(key.as_slice())?.map(|b| b.value().to_vec()).unwrap_or_default();
                    let json = info.get(key.as_slice())?.map(|j| j.value().to_string()).unwrap_or_default();
                    size += bytes.len();
                    batch.push((key.clone(), bytes, json));
                    next += 1;
                }
                Ok(batch)
            })?;
            self.copy(input, &batch, &mut stats)?;
        }
        self.merge_tables(input)?;
        Ok(stats)
    }

    /// Checks and copies one batch of `input`'s artefacts in one transaction.
    fn copy(&self, input: &Store, batch: &[(Vec<u8>, Vec<u8>, String)], stats: &mut MergeStats) -> Result<()> {
        for (key, bytes, json) in batch {
            accept(key, bytes, json).map_err(|detail| DbError::Storage { path: input.path.clone(), detail })?;
        }
        let mut conflict = None;
        let mut counts = MergeStats::default();
        self.write(|t| {
            let (mut artefacts, mut info) = (t.open_table(ARTEFACTS)?, t.open_table(INFO)?);
            for (key, bytes, json) in batch {
                let held = info.get(key.as_slice())?.and_then(|j| checksum_of(j.value()));
                match held {
                    Some(sum) if sum == *blake3::hash(bytes).as_bytes() => counts.present += 1,
                    Some(_) => {
                        conflict = Some(Key::from_slice(key));
                        return Ok(());
                    }
                    None => {
                        artefacts.insert(key.as_slice(), bytes.as_slice())?;
                        info.insert(key.as_slice(), json.as_str())?;
                        counts.added += 1;
                        counts.bytes += bytes.len() as u64;
                    }
                }
            }
            Ok(())
        })?;
        if let Some(key) = conflict {
            return Err(DbError::Storage {
                path: input.path.clone(),
                detail: format!(
                    "artefact {} differs from the one {} holds under the same bake key (nothing of this batch was merged)",
                    key.short(),
                    self.path.display()
                ),
            });
        }
        stats.added += counts.added;
        stats.present += counts.present;
        stats.bytes += counts.bytes;
        Ok(())
    }

    /// Merges the small tables: meshes and extras as unions, scene records as the union of
    /// their keys, lineage as `input`'s entries (shards bake disjoint slots; a later bake's
    /// lineage supersedes an earlier one's), occluder triangles where the target has none,
    /// metadata where the target has none — and an error when both hold a different value (a
    /// different parameter plan for the same scene).
    fn merge_tables(&self, input: &Store) -> Result<()> {
        let read_all = |table: TableDefinition<&[u8], &[u8]>| {
            input.read(|t| {
                rows(t.open_table(table)?.iter()?.map(|r| r.map(|(k, v)| (k.value().to_vec(), v.value().to_vec()))))
            })
        };
        let read_named = |table: TableDefinition<&str, &[u8]>| {
            input.read(|t| match t.open_table(table) {
                Ok(tab) => rows(tab.iter()?.map(|r| r.map(|(k, v)| (k.value().to_string(), v.value().to_vec())))),
                Err(redb::TableError::TableDoesNotExist(_)) => Ok(Vec::new()),
                Err(e) => Err(e.into()),
            })
        };
        let (meshes, lineage) = (read_all(MESHES)?, read_all(LINEAGE)?);
        let (scenes, extras, meta) = (read_named(SCENES)?, read_named(EXTRAS)?, read_named(META)?);
        let mut disagree = None;
        self.write(|t| {
            let mut m = t.open_table(MESHES)?;
            for (k, v) in &meshes {
                if m.get(k.as_slice())?.is_none() {
                    m.insert(k.as_slice(), v.as_slice())?;
                }
            }
            drop(m);
            let mut l = t.open_table(LINEAGE)?;
            for (k, v) in &lineage {
                l.insert(k.as_slice(), v.as_slice())?;
            }
            drop(l);
            for (table, entries, width) in [(SCENES, &scenes, 32), (EXTRAS, &extras, 64)] {
                let mut tab = t.open_table(table)?;
                for (name, v) in entries {
                    let held = tab.get(name.as_str())?.map(|h| h.value().to_vec()).unwrap_or_default();
                    let merged = union(&held, v, width);
                    if merged != held {
                        tab.insert(name.as_str(), merged.as_slice())?;
                    }
                }
            }
            let mut tab = t.open_table(META)?;
            for (name, v) in &meta {
                let held = tab.get(name.as_str())?.map(|h| h.value().to_vec());
                match held {
                    None => drop(tab.insert(name.as_str(), v.as_slice())?),
                    Some(h) if h != *v => disagree = Some(name.clone()),
                    Some(_) => {}
                }
            }
            Ok(())
        })?;
        match disagree {
            Some(name) => Err(DbError::Storage {
                path: input.path.clone(),
                detail: format!(
                    "its metadata '{name}' differs from {}'s (a different parameter plan)",
                    self.path.display()
                ),
            }),
            None => Ok(()),
        }
    }
}

/// Collects a table's rows.
fn rows<T>(
    it: impl Iterator<Item = std::result::Result<T, redb::StorageError>>,
) -> std::result::Result<Vec<T>, redb::Error> {
    it.map(|r| r.map_err(redb::Error::from)).collect()
}

/// `held`'s entries of `width` bytes, then `new`'s that `held` lacks.
fn union(held: &[u8], new: &[u8], width: usize) -> Vec<u8> {
    let mut out = held.to_vec();
    for e in new.chunks_exact(width) {
        if !held.chunks_exact(width).any(|h| h == e) {
            out.extend_from_slice(e);
        }
    }
    out
}

/// Checks one artefact of a database being merged: a 32-byte key, metadata whose checksum
/// matches the bytes, and the algorithm (or layout) version this kage bakes with.
fn accept(key: &[u8], bytes: &[u8], json: &str) -> std::result::Result<(), String> {
    let short = Key::from_slice(key).short();
    if key.len() != 32 {
        return Err(format!("a bake key of {} bytes", key.len()));
    }
    let info = Info::parse(json).ok_or_else(|| format!("artefact {short} has no readable metadata"))?;
    if info.checksum != *blake3::hash(bytes).as_bytes() {
        return Err(format!("artefact {short} does not match its checksum (damaged)"));
    }
    let (word, version) = match info.kind.as_str() {
        "bspvt" => ("algorithm", kage_engine::bspvt::ALGORITHM_VERSION),
        "prt" => ("algorithm", kage_engine::prt::ALGORITHM_VERSION),
        "hsh-cache" => ("layout", crate::memo::records::VERSION),
        other => return Err(format!("artefact {short} is of an unknown kind '{other}'")),
    };
    let found = info
        .params
        .split(", ")
        .find_map(|p| p.strip_prefix(word)?.trim().parse::<u32>().ok())
        .ok_or_else(|| format!("artefact {short} does not record its {word} version"))?;
    if found != version {
        return Err(format!("artefact {short} is {} {word} {found}; this kage bakes {word} {version}", info.kind));
    }
    Ok(())
}
