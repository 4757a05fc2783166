//! What baking a plan's jobs needs beyond the plan — the occluders' BVHs, the subtree memo,
//! PRT's baker — set up once per run for the kinds it bakes, and the per-job bake
//! ([`Context`]) that uses them.

use super::*;
use std::sync::Arc;

/// What baking jobs needs beyond the plan, set up only for the kinds a set of jobs has.
pub(crate) struct Tools {
    /// BSPVT's prepared baker, when the jobs hold BSPVT chunks.
    pub(super) bspvt: Option<BspvtBaker>,
    /// PRT's prepared baker, when the jobs hold PRT chunks.
    pub(super) prt: Option<PrtBaker>,
    /// Occluder BVHs built now, as memos to store.
    pub(super) new_bvhs: Vec<(String, Vec<u8>)>,
    /// Per instance, which listed slot held each vertex, read once for every chunk that asks
    /// ([`Context::lineage_of`]).
    pub(super) holders: Mutex<HashMap<usize, Arc<Holders>>>,
}

/// What a BSPVT chunk bakes with: the occluders' BVHs and the tile subtree memo.
pub(crate) struct BspvtBaker {
    pub(super) occluders: Occluders,
    pub(super) tiles: bspvt::memo::SubtreeMemo,
}

/// What a PRT chunk bakes with: the transfer baker and its settings.
pub(crate) struct PrtBaker {
    pub(super) baker: prt::Baker,
    pub(super) settings: prt::Settings,
}

impl Tools {
    pub(crate) fn for_jobs(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan, jobs: &[&Job]) -> Result<Self> {
        let baking = |kind: Kind| jobs.iter().any(|j| j.kind == kind);
        let (mut new_bvhs, mut bspvt) = (Vec::new(), None);
        if let Some(s) = plan.bspvt.filter(|_| baking(Kind::Bspvt)) {
            let occluders;
            (occluders, new_bvhs) = crate::memo::bvhs::occluders(store, flat)?;
            bspvt = Some(BspvtBaker { occluders, tiles: load_tiles(store, &s)? });
        }
        let prt = plan.prt.filter(|_| baking(Kind::Prt));
        let prt = prt.map(|settings| PrtBaker { baker: prt::Baker::new(scene, flat, &settings), settings });
        Ok(Tools { bspvt, prt, new_bvhs, holders: Mutex::default() })
    }

    pub(crate) fn context<'a>(&'a self, store: &'a Store, flat: &'a FlatScene, plan: &'a Plan) -> Context<'a> {
        Context { flat, plan, store, bspvt: self.bspvt.as_ref(), prt: self.prt.as_ref(), holders: &self.holders }
    }

    /// The memos worth storing: new occluder BVHs and the subtree memo when it grew.
    pub(super) fn memos(&self) -> Vec<(String, Vec<u8>)> {
        let grown = self.bspvt.as_ref().map(|b| &b.tiles).filter(|t| t.added() > 0);
        let tiles = grown.map(|t| (tiles_name(t.settings()), t.to_bytes()));
        self.new_bvhs.iter().cloned().chain(tiles).collect()
    }
}

pub(crate) struct Context<'a> {
    pub(super) flat: &'a FlatScene,
    pub(super) plan: &'a Plan,
    pub(super) store: &'a Store,
    pub(super) bspvt: Option<&'a BspvtBaker>,
    pub(super) prt: Option<&'a PrtBaker>,
    pub(super) holders: &'a Mutex<HashMap<usize, Arc<Holders>>>,
}

impl Context<'_> {
    pub(super) fn bake<'j>(&self, job: &'j Job) -> Result<Baked<'j>> {
        let t = Instant::now();
        let mut lineage = job.slot.map(|slot| {
            let mut v = LINEAGE_MAGIC.to_vec();
            v.extend_from_slice(job.key.as_bytes());
            let occluders = encode_occluders(&self.plan.snapshot.occluders);
            v.extend_from_slice(&(occluders.len() as u32).to_le_bytes());
            v.extend(occluders);
            (slot, v)
        });
        let (bytes, warm, vertices, rays, tiles) = match (job.kind, self.bspvt, self.prt) {
            (Kind::Prt, _, Some(PrtBaker { baker, settings })) => {
                let n = settings.order * settings.order;
                let mut out = vec![0.0f32; job.vertices.len() * n];
                for (k, v) in job.vertices.clone().enumerate() {
                    baker.vertex(self.flat, job.instance, v, &mut out[k * n..(k + 1) * n]);
                }
                (bytemuck::cast_slice(&out).to_vec(), false, job.vertices.len(), 0, 0)
            }
            (Kind::Bspvt, Some(prepared), _) => {
                let (baked, warm) = self.bake_bspvt(prepared, job)?;
                if let Some((_, v)) = &mut lineage {
                    v.extend_from_slice(&(job.vertices.len() as u32).to_le_bytes());
                    let bits = job.vertices.clone().map(|k| crate::plan::vertex_bits(self.flat, job.instance, k));
                    bits.for_each(|b| v.extend_from_slice(bytemuck::cast_slice(&b)));
                    baked.iter().for_each(|b| encode_masks(&b.masks, v));
                }
                let touched = baked.iter().filter(|b| b.rays > 0).count();
                let (rays, tiles) = baked.iter().fold((0, 0), |(r, t), b| (r + b.rays, t + b.built));
                let records: Vec<Vec<u8>> = baked.into_iter().map(|b| b.record).collect();
                (encode_records(&records), warm, touched, rays, tiles)
            }
            // Tools are prepared from the very jobs they bake: a kind without its baker is a
            // caller's mistake, reported rather than baked wrong.
            (kind, ..) => {
                let detail = format!("no {} baker was prepared for its chunk", kind.name());
                return Err(DbError::Storage { path: self.store.path().to_path_buf(), detail });
            }
        };
        let info = Info {
            kind: job.kind.name().into(),
            params: self.plan.params(job.kind),
            seconds: t.elapsed().as_secs_f64(),
            // Warm chunks are not representative of a bake's cost per vertex.
            vertices: if warm { 0 } else { job.vertices.len() },
            checksum: *blake3::hash(&bytes).as_bytes(),
        };
        Ok(Baked { job, key: job.key, bytes, info, lineage, warm, vertices, rays, tiles })
    }

    /// The chunk's vertex bakes, and whether any was re-baked warm from the lineage.
    pub(super) fn bake_bspvt(&self, prepared: &BspvtBaker, job: &Job) -> Result<(Vec<bspvt::VertexBake>, bool)> {
        let (occ, tiles) = (&prepared.occluders, &prepared.tiles);
        let vertex = |v: usize| self.flat.vertex(job.instance, v);
        let old = self.lineage_of(job)?;
        let warm = old.iter().any(Option::is_some);
        let cold = bspvt::VertexBake::default();
        // The vertices in parallel too: a worker that runs out of chunks helps with the ones
        // still baking, so a large chunk (the moved object's own, baked cold) does not end a
        // run on one core. Collected in order: the same bytes on any thread count.
        let baked = job
            .vertices
            .clone()
            .into_par_iter()
            .zip(&old)
            .map(|(v, old)| {
                let (p, n) = vertex(v);
                // A new vertex bakes cold: no change needs looking at.
                let (old, changed) = old.as_ref().map_or((&cold, &[][..]), |(old, changed)| (old, &changed[..]));
                bspvt::rebake_vertex(occ, p, n, (tiles, &self.plan.reach), old, changed)
            })
            .collect();
        Ok((baked, warm))
    }

    /// The previous bake of each of the chunk's vertices (matched by position and normal) and
    /// the occluders that changed since: from the slot's lineage, and for the vertices it does
    /// not hold from the instance's other slots (see [`Plan::slot_lists`]). All `None` for a
    /// chunk without a slot (baked cold on purpose). Any previous bake of a vertex gives the
    /// same bytes: a warm re-bake equals a cold one.
    pub(super) fn lineage_of(&self, job: &Job) -> Result<Lineage> {
        let mut lineage: Lineage = vec![None; job.vertices.len()];
        let Some(slot) = job.slot else { return Ok(lineage) };
        let bits: Vec<[u32; 6]> =
            job.vertices.clone().map(|v| crate::plan::vertex_bits(self.flat, job.instance, v)).collect();
        self.fill(&mut lineage, &bits, slot)?;
        if lineage.iter().any(Option::is_none) {
            let holders = self.holders(job.instance)?;
            let mut elsewhere: Vec<Key> = lineage
                .iter()
                .zip(&bits)
                .filter(|(l, _)| l.is_none())
                .filter_map(|(_, b)| holders.get(b).copied())
                .collect();
            elsewhere.sort_unstable_by_key(|k| *k.as_bytes());
            elsewhere.dedup();
            for other in elsewhere.into_iter().filter(|k| *k != slot) {
                self.fill(&mut lineage, &bits, other)?;
            }
        }
        Ok(lineage)
    }

    /// Fills the `None`s of `lineage` (for vertices `bits`) that `slot`'s entry holds.
    fn fill(&self, lineage: &mut Lineage, bits: &[[u32; 6]], slot: Key) -> Result<()> {
        if let Some(mut held) = self.entry(&slot)? {
            lineage.iter_mut().zip(bits).filter(|(l, _)| l.is_none()).for_each(|(l, b)| *l = held.remove(b));
        }
        Ok(())
    }

    /// Which of instance `i`'s listed slots held each vertex (by its bits) — vertices only, not
    /// their bakes, so that memory stays bounded by the index (56 bytes a vertex); read once
    /// per run (the other workers wait rather than read it again).
    fn holders(&self, i: usize) -> Result<Arc<Holders>> {
        let mut all = self.holders.lock().expect("no worker panics holding it");
        if let Some(holders) = all.get(&i) {
            return Ok(holders.clone());
        }
        let list = self.plan.slot_lists.get(i).copied().flatten();
        let entry = list.map(|k| self.store.lineage(&k)).transpose()?.flatten();
        let mut holders = Holders::new();
        for slot in entry.as_deref().and_then(decode_slot_list).unwrap_or_default() {
            let then = self.store.lineage(&slot)?.and_then(|e| decode_lineage(&e));
            holders.extend(then.into_iter().flat_map(|t| t.vertices).map(|b| (b, slot)));
        }
        let holders = Arc::new(holders);
        all.insert(i, holders.clone());
        Ok(holders)
    }

    /// A slot's lineage entry: its vertices' previous bakes by their bits, each with every
    /// occluder that changed since; `None` when the slot has none or it is unusable.
    fn entry(&self, slot: &Key) -> Result<Option<Held>> {
        let Some(entry) = self.store.lineage(slot)? else { return Ok(None) };
        let Some(Then { key, occluders, vertices, masks }) = decode_lineage(&entry) else { return Ok(None) };
        let Some(bytes) = self.store.get::<u8>(&key)? else { return Ok(None) };
        // The warm re-bake descends the old trees: a damaged chunk bakes cold instead.
        let usable = |r: &Vec<Vec<u8>>| {
            let res = self.plan.bspvt.map_or(0, |s| s.res);
            r.len() == vertices.len() && r.iter().all(|rec| bspvt::layout::check_record(rec, res).is_ok())
        };
        let Some(records) = decode_records(&bytes).filter(usable) else { return Ok(None) };
        let changed: Arc<[bspvt::Change]> = changes(&occluders, &self.plan.snapshot.occluders).into();
        let bakes = records.into_iter().zip(masks).map(|(record, masks)| bspvt::VertexBake {
            record,
            masks,
            ..Default::default()
        });
        Ok(Some(vertices.into_iter().zip(bakes.map(|b| (b, changed.clone()))).collect()))
    }
}

/// The store's name for the subtree memo of `s`.
pub fn tiles_name(s: &bspvt::Settings) -> String {
    format!("bspvt tiles v{} res {} eps {}", bspvt::ALGORITHM_VERSION, s.res, s.epsilon)
}

/// The stored subtree memo for `s`, or an empty one (none stored, or damaged: it only costs time).
pub(super) fn load_tiles(store: &Store, s: &bspvt::Settings) -> Result<bspvt::memo::SubtreeMemo> {
    let stored = store.memo(&tiles_name(s))?;
    Ok(stored
        .and_then(|b| bspvt::memo::SubtreeMemo::from_bytes(s, &b))
        .unwrap_or_else(|| bspvt::memo::SubtreeMemo::new(s)))
}
