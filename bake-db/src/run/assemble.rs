//! Assembly: every chunk of a plan (baked now or cached) decoded and written into the engine's
//! bakes.

use super::*;

/// A BSPVT chunk: u32 count, count + 1 u32 offsets, then the records.
pub(super) fn encode_records(records: &[Vec<u8>]) -> Vec<u8> {
    let mut offsets = vec![0u32];
    for r in records {
        offsets.push(offsets[offsets.len() - 1] + r.len() as u32);
    }
    let mut out = (records.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(bytemuck::cast_slice(&offsets));
    records.iter().for_each(|r| out.extend_from_slice(r));
    out
}

/// The offsets and data of a BSPVT chunk (`None` when malformed).
pub(super) fn chunk_parts(bytes: &[u8]) -> Option<(Vec<u32>, &[u8])> {
    let count = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?) as usize;
    let end = 4 + 4 * (count + 1);
    let offsets: Vec<u32> = bytemuck::pod_collect_to_vec(bytes.get(4..end)?);
    let data = bytes.get(end..)?;
    (offsets.windows(2).all(|w| w[0] <= w[1]) && *offsets.last()? as usize == data.len()).then_some((offsets, data))
}

pub(super) fn decode_records(bytes: &[u8]) -> Option<Vec<Vec<u8>>> {
    let (offsets, data) = chunk_parts(bytes)?;
    Some(offsets.windows(2).map(|w| data[w[0] as usize..w[1] as usize].to_vec()).collect())
}

/// Builds the engine's bakes from the chunks, fresh or from the store (all read in one
/// transaction and borrowed, so each stored byte is copied once, into the bake).
pub(super) fn assemble(
    store: &Store,
    flat: &FlatScene,
    plan: &Plan,
    fresh: &HashMap<Key, Vec<u8>>,
    stats: RunStats,
) -> Result<Assembled> {
    let stored: Vec<Key> = plan.jobs.iter().map(|j| j.key).filter(|k| !fresh.contains_key(k)).collect();
    let checked = store.with_checked_artefacts(&stored, |found| {
        let mut found = found.iter();
        let chunks: Vec<&[u8]> = plan
            .jobs
            .iter()
            .map(|j| {
                fresh.get(&j.key).map_or_else(|| found.next().copied().flatten().unwrap_or_default(), Vec::as_slice)
            })
            .collect();
        bakes(store, flat, plan, &chunks, stats)
    })?;
    Ok(match checked {
        Ok(outcome) => Assembled::Done(outcome),
        Err(damaged) => Assembled::Damaged(damaged),
    })
}

/// A plan's bakes, or the stored chunks that failed their checksum.
pub(super) enum Assembled {
    Done(Outcome),
    Damaged(Vec<Key>),
}

/// A stored chunk, checked: a BSPVT chunk's offsets and records, or a PRT chunk's coefficients.
pub(super) enum Part<'a> {
    Trees(Vec<u32>, &'a [u8]),
    Transfer(&'a [u8]),
}

/// Checks that a chunk holds what its job needs (every BSPVT tree is walked: a damaged one
/// would panic in the tree descent; a PRT chunk must hold `coeffs` floats per vertex; `res`
/// is BSPVT's face resolution).
pub(super) fn part<'a>(store: &Store, job: &Job, bytes: &'a [u8], (coeffs, res): (usize, usize)) -> Result<Part<'a>> {
    let malformed = |why: String| {
        let kind = if job.kind == Kind::Bspvt { "BSPVT" } else { "PRT" };
        DbError::Corrupted {
            path: store.path().to_path_buf(),
            detail: format!("{kind} artefact {} is malformed{why} (run `kage db check`)", job.key.short()),
        }
    };
    if job.kind == Kind::Prt {
        let expected = 4 * coeffs * job.vertices.len();
        if bytes.len() != expected {
            let why = format!(": {} bytes where its {} vertices need {expected}", bytes.len(), job.vertices.len());
            return Err(malformed(why));
        }
        return Ok(Part::Transfer(bytes));
    }
    let (offsets, data) = chunk_parts(bytes)
        .filter(|(o, _)| o.len() == job.vertices.len() + 1)
        .ok_or_else(|| malformed(String::new()))?;
    for (v, w) in offsets.windows(2).enumerate() {
        bspvt::layout::check_record(&data[w[0] as usize..w[1] as usize], res)
            .map_err(|e| malformed(format!(": vertex {}: {e}", job.vertices.start + v)))?;
    }
    Ok(Part::Trees(offsets, data))
}

/// The engine's bakes from every job's chunk (in plan order); each instance's buffers are sized
/// once from its chunks' lengths.
pub(super) fn bakes(
    store: &Store,
    flat: &FlatScene,
    plan: &Plan,
    chunks: &[&[u8]],
    stats: RunStats,
) -> Result<Outcome> {
    let per_instance = |kind: Kind| {
        let mut bytes = vec![0usize; flat.instances.len()];
        plan.jobs.iter().zip(chunks).filter(|(j, _)| j.kind == kind).for_each(|(j, c)| bytes[j.instance] += c.len());
        bytes
    };
    let mut bspvt_instances: Vec<bspvt::BakedInstance> = match plan.bspvt {
        Some(_) => per_instance(Kind::Bspvt)
            .into_iter()
            .map(|n| bspvt::BakedInstance { offsets: vec![0], data: Vec::with_capacity(n) })
            .collect(),
        None => Vec::new(),
    };
    let mut prt_instances: Vec<Vec<f32>> = match plan.prt {
        Some(_) => per_instance(Kind::Prt).into_iter().map(|n| Vec::with_capacity(n / 4)).collect(),
        None => Vec::new(),
    };
    // Checked chunk by chunk in parallel: walking the trees is most of loading's time.
    let sizes = (plan.prt.map_or(0, |s| s.order * s.order), plan.bspvt.map_or(0, |s| s.res));
    let parts: Vec<Part> =
        plan.jobs.par_iter().zip(chunks).map(|(job, &bytes)| part(store, job, bytes, sizes)).collect::<Result<_>>()?;
    let mut leaves_bytes = 0usize;
    for (job, part) in plan.jobs.iter().zip(parts) {
        match part {
            Part::Trees(offsets, data) => {
                let inst = &mut bspvt_instances[job.instance];
                let base = inst.data.len() as u32;
                inst.offsets.extend(offsets[1..].iter().map(|o| base + o));
                inst.data.extend_from_slice(data);
                leaves_bytes += data.len();
            }
            Part::Transfer(bytes) => {
                // One copy into aligned memory (redb's bytes are not aligned for f32).
                let t = &mut prt_instances[job.instance];
                let start = t.len();
                t.resize(start + bytes.len() / 4, 0.0);
                bytemuck::cast_slice_mut::<f32, u8>(&mut t[start..]).copy_from_slice(bytes);
            }
        }
    }
    let vertices: usize = (0..flat.instances.len()).map(|i| flat.vertex_count(i)).sum();
    let bspvt = plan.bspvt.map(|settings| bspvt::Bake {
        settings,
        instances: bspvt_instances,
        stats: bspvt::Stats { vertices, bytes: leaves_bytes, ..Default::default() },
    });
    let prt = plan.prt.map(|s| {
        let bytes = prt_instances.iter().map(|t| t.len() * 4).sum();
        prt::Bake { order: s.order, instances: prt_instances, stats: prt::Stats { vertices, bytes, seconds: 0.0 } }
    });
    Ok(Outcome { bspvt, prt, stats })
}
