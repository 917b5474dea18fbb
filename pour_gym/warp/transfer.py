"""Label transfer from a labelled source mesh to a target mesh (thesis 4.2 and 4.3).

Two methods, comparable on the same objects:

``"thesis"``: the thesis's pipeline. Local features (4.1.1) feed a logistic regression for
the rim and a Gaussian generative classifier for the handle, both trained on the source
(4.1.3). On the target's rough labels, the source is aligned (4.2): its container centre
(the vertices classified neither rim nor handle) is moved onto the target's, rotated so
that the directions to the rim centres agree, rotated about that axis so that the handle
centres agree (when both have a handle), and scaled per axis by the ratio of the standard
deviations. Each target vertex then takes the label of its forward correspondence (4.3),
the nearest source vertex whose normal is within ``delta`` of its own.

``"best"``: both meshes are put in the canonical frame (:mod:`pour_gym.warp.frame`:
upright, rim axis at the origin, handle along +x) and normalised rim to rim and base to
base; the forward correspondence is taken there, combined with the backward one (each source
vertex votes for its nearest target vertex, so a thin source rim still reaches every target
vertex of a broad rim band and one source vertex does not paint many target vertices),
and the labels are smoothed over the target's mesh graph by a few rounds of majority vote;
last, the rim is fitted to the target's own lip (:mod:`pour_gym.warp.lip`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.spatial import cKDTree

from pour_gym.parts import Part
from pour_gym.warp.classifiers import GaussianGenerative, LogisticRegression
from pour_gym.warp.frame import ContainerFrame, canonical_frame
from pour_gym.warp.lip import fit_rim
from pour_gym.warp.local_features import local_features

Method = Literal["thesis", "best"]
N_PARTS = len(Part)


@dataclass
class Transfer:
    """The result of a label transfer.

    Attributes:
        labels: (V,) int8 part of each target vertex.
        method: ``"thesis"`` or ``"best"``.
        frame: the target's canonical frame (``"best"``), else ``None``.
        info: diagnostics (JSON-serialisable).
    """

    labels: np.ndarray
    method: str
    frame: ContainerFrame | None = None
    info: dict = field(default_factory=dict)


def forward_correspondence(
    target_points: np.ndarray,
    target_normals: np.ndarray,
    source_points: np.ndarray,
    source_normals: np.ndarray,
    delta: float = np.pi / 2,
    k: int = 32,
) -> np.ndarray:
    """C_f(t): the nearest source vertex whose normal is within ``delta`` of t's normal.

    Args:
        target_points: (T, 3) target positions.
        target_normals: (T, 3) unit normals of the target.
        source_points: (S, 3) aligned source positions.
        source_normals: (S, 3) unit normals of the aligned source.
        delta: largest angle between the normals, in rad (thesis: pi / 2).
        k: nearest candidates examined first; for the target vertices without a compatible
            one among them the search widens (x8) until it finds one.

    Returns:
        (T,) index of the corresponding source vertex.
    """
    k = min(k, len(source_points))
    tree = cKDTree(source_points)
    cos_delta = np.cos(delta)
    result = np.empty(len(target_points), dtype=np.int64)
    todo = np.arange(len(target_points))
    # Widen the search only for the vertices whose nearest candidates all face the wrong
    # way (a target wall next to the source's other side of the wall).
    while len(todo):
        _, idx = tree.query(target_points[todo], k=k)
        idx = idx.reshape(len(todo), k)
        ok = np.einsum("tkd,td->tk", source_normals[idx], target_normals[todo]) > cos_delta
        found = ok.any(axis=1)
        result[todo[found]] = idx[found, ok[found].argmax(axis=1)]
        todo = todo[~found]
        if k >= len(source_points) and len(todo):
            result[todo] = idx[~found, 0]  # no source normal is compatible: the nearest
            break
        k = min(8 * k, len(source_points))
    return result


def _vertex_normals(mesh: trimesh.Trimesh) -> np.ndarray:
    n = np.asarray(mesh.vertex_normals, dtype=float)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def _smooth_labels(mesh: trimesh.Trimesh, labels: np.ndarray, rounds: int) -> np.ndarray:
    """Majority vote of each vertex and its mesh neighbours, repeated ``rounds`` times."""
    edges = mesh.edges_unique
    n = len(mesh.vertices)
    rows = np.concatenate([edges[:, 0], edges[:, 1], np.arange(n)])
    cols = np.concatenate([edges[:, 1], edges[:, 0], np.arange(n)])
    adj = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)).tocsr()
    out = labels.copy()
    for _ in range(rounds):
        onehot = np.eye(N_PARTS)[out]
        votes = adj @ onehot
        # Ties keep the current label: it gets a small bonus.
        out = np.argmax(votes + 0.5 * onehot, axis=1)
    return out.astype(np.int8)


def transfer_best(
    source: trimesh.Trimesh,
    source_labels: np.ndarray,
    target: trimesh.Trimesh,
    delta: float = np.pi / 2,
    smoothing_rounds: int = 2,
    source_upright: bool = True,
    target_upright: bool = False,
    fit_lip: bool = True,
) -> Transfer:
    """Label transfer in the normalised canonical frames (the ``"best"`` method).

    Args:
        source: labelled source mesh, in m.
        source_labels: (S,) parts of the source's vertices.
        target: the mesh to label, any pose, in m.
        delta: normal-angle limit of the correspondences, in rad.
        smoothing_rounds: rounds of majority vote over the target's mesh graph.
        source_upright: the source already stands upright on +z.
        target_upright: the target already stands upright on +z (skips the search).
        fit_lip: fit the warped rim to the target's lip (:func:`pour_gym.warp.lip.fit_rim`);
            False gives the warp's band as it is.

    Returns:
        The target's labels and frame.
    """
    sf = canonical_frame(source, upright=source_upright)
    tf = canonical_frame(target, upright=target_upright)
    sc = sf.apply(np.asarray(source.vertices))
    tc = tf.apply(np.asarray(target.vertices))
    sp, sn = sf.normalise(sc), sf.normalise_normals(sc, sf.rotate(_vertex_normals(source)))
    tp, tn = tf.normalise(tc), tf.normalise_normals(tc, tf.rotate(_vertex_normals(target)))
    source_labels = np.asarray(source_labels)
    if not tf.handle:
        # A target without a handle has nothing for the source's handle to map onto: the
        # source's handle vertices do not take part.
        keep = source_labels != Part.HANDLE
        sp, sn, source_labels = sp[keep], sn[keep], source_labels[keep]
    fwd = source_labels[forward_correspondence(tp, tn, sp, sn, delta)]
    # Backward: every source vertex votes for its nearest compatible target vertex.
    bwd_target = forward_correspondence(sp, sn, tp, tn, delta)
    votes = np.zeros((len(tp), N_PARTS))
    np.add.at(votes, (bwd_target, source_labels), 1.0)
    votes[np.arange(len(tp)), fwd] += 1.0
    labels = np.argmax(votes, axis=1).astype(np.int8)
    if tf.handle:
        # Whatever stands well clear of the body (by the frame's own body profile) is the
        # handle, however its normals point: coarse meshes average them across the bend.
        radial = np.hypot(tp[:, 0], tp[:, 1])
        labels[(radial > 1.2) & (tp[:, 2] < 0.95)] = Part.HANDLE
    if smoothing_rounds:
        labels = _smooth_labels(target, labels, smoothing_rounds)
    info = {"target_handle_found": tf.handle, "height": tf.height, "rim_radius": tf.rim_radius}
    if fit_lip:
        placed = trimesh.Trimesh(tc, target.faces, process=False)
        labels, lip = fit_rim(placed, labels, rim_top=tf.rim_top)
        info["lip"] = lip.to_dict()
    return Transfer(labels=labels, method="best", frame=tf, info=info)


@dataclass
class InitialClassifier:
    """The thesis's initial classification (4.1).

    Rim by logistic regression, handle by the generative classifier, both on local
    features, trained on the labelled source.
    """

    rim: LogisticRegression
    handle: GaussianGenerative | None

    @classmethod
    def train(cls, source: trimesh.Trimesh, labels: np.ndarray) -> InitialClassifier:
        """Fit both classifiers on the source's vertices."""
        x = local_features(source.vertices)
        labels = np.asarray(labels)
        rim = LogisticRegression(lam=1e-2).fit(x, labels == Part.RIM)
        handle = None
        if np.any(labels == Part.HANDLE):
            handle = GaussianGenerative().fit(x, labels == Part.HANDLE)
        return cls(rim=rim, handle=handle)

    def predict(self, mesh: trimesh.Trimesh) -> np.ndarray:
        """Rough labels: rim, handle, or container (everything else)."""
        x = local_features(mesh.vertices)
        labels = np.full(len(x), int(Part.CONTAINER), dtype=np.int8)
        if self.handle is not None:
            labels[self.handle.predict_proba(x) > 0.5] = Part.HANDLE
        labels[self.rim.predict_proba(x) > 0.5] = Part.RIM
        return labels


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation taking direction a onto direction b."""
    return trimesh.geometry.align_vectors(a, b)[:3, :3]


def _centre(points: np.ndarray, mask: np.ndarray) -> np.ndarray | None:
    return points[mask].mean(axis=0) if mask.sum() >= 3 else None


def transfer_thesis(
    source: trimesh.Trimesh,
    source_labels: np.ndarray,
    target: trimesh.Trimesh,
    delta: float = np.pi / 2,
    classifier: InitialClassifier | None = None,
) -> Transfer:
    """The thesis's label transfer: initial classification, part alignment, C_f.

    Args:
        source: labelled source mesh, in m.
        source_labels: (S,) parts of the source's vertices.
        target: the mesh to label, in m.
        delta: normal-angle limit of the forward correspondence, in rad.
        classifier: a trained initial classifier (trained on the source if None).

    Returns:
        The target's labels; ``info`` holds the rough labels' counts.
    """
    clf = classifier or InitialClassifier.train(source, source_labels)
    rough = clf.predict(target)
    sp = np.asarray(source.vertices, dtype=float)
    tp = np.asarray(target.vertices, dtype=float)
    sl = np.asarray(source_labels)
    # Part centres from the source's own labels (hand-labelled, as in the thesis) and the
    # target's rough ones.
    s_cont = _centre(sp, (sl != Part.RIM) & (sl != Part.HANDLE))
    t_cont = _centre(tp, (rough != Part.RIM) & (rough != Part.HANDLE))
    if s_cont is None or t_cont is None:
        s_cont, t_cont = sp.mean(axis=0), tp.mean(axis=0)
    aligned = sp - s_cont
    s_rim, t_rim = _centre(sp, sl == Part.RIM), _centre(tp, rough == Part.RIM)
    rot = np.eye(3)
    if s_rim is not None and t_rim is not None:
        rot = _rotation_between(s_rim - s_cont, t_rim - t_cont)
    aligned = aligned @ rot.T
    s_h, t_h = _centre(sp, sl == Part.HANDLE), _centre(tp, rough == Part.HANDLE)
    if s_h is not None and t_h is not None and t_rim is not None:
        axis = (t_rim - t_cont) / np.linalg.norm(t_rim - t_cont)

        def flat(d: np.ndarray) -> np.ndarray:
            return d - axis * (d @ axis)

        a, b = flat(rot @ (s_h - s_cont)), flat(t_h - t_cont)
        if np.linalg.norm(a) > 1e-9 and np.linalg.norm(b) > 1e-9:
            spin = _rotation_between(a, b)
            aligned = aligned @ spin.T
            rot = spin @ rot
    aligned = aligned * (tp.std(axis=0) / np.maximum(aligned.std(axis=0), 1e-12)) + t_cont
    sn = _vertex_normals(source) @ rot.T
    tn = _vertex_normals(target)
    labels = sl[forward_correspondence(tp, tn, aligned, sn, delta)].astype(np.int8)
    counts = np.bincount(rough, minlength=N_PARTS)
    return Transfer(
        labels=labels,
        method="thesis",
        info={"rough_counts": {p.name.lower(): int(counts[p]) for p in Part}},
    )
