"""The BLAS-free kernels of grasp_env.solvers.dense against numpy's and scipy's LAPACK-backed
routines (the reference), on random, scaled and rank-deficient problems."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls

from grasp_env.solvers import dense


def problems(seed: int, count: int = 400):
    """Random (A, b): 1-6 rows and columns, entries scaled by 1e-3..1e3, a third with a
    column that is a multiple of another (rank-deficient)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        m, n = (int(x) for x in rng.integers(1, 7, 2))
        A = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-3, 3)
        if n > 1 and rng.random() < 0.3:
            A[:, -1] = A[:, 0] * rng.normal()
        yield A, rng.normal(size=m)


def test_products_match_numpy() -> None:
    for A, b in problems(0, 100):
        x = np.random.default_rng(1).normal(size=A.shape[1])
        np.testing.assert_allclose(dense.matvec(A, x), A @ x, rtol=1e-13, atol=1e-13 * abs(A).max())
        np.testing.assert_allclose(
            dense.rmatvec(A, b), A.T @ b, rtol=1e-13, atol=1e-12 * abs(A).max()
        )
        np.testing.assert_allclose(
            dense.matmul(A, A.T), A @ A.T, rtol=1e-13, atol=1e-12 * abs(A).max() ** 2
        )
        assert dense.dot(b, b) == pytest.approx(float(np.dot(b, b)), rel=1e-14)


def test_svd_matches_lapack() -> None:
    for A, _ in problems(2):
        U, s, V = dense.svd(A)
        ref = np.linalg.svd(A, compute_uv=False)
        np.testing.assert_allclose(s[: len(ref)], ref, atol=1e-14 * ref.max())
        assert np.all(np.diff(s) <= 0.0)
        np.testing.assert_allclose((U * s) @ V.T, A, atol=1e-13 * abs(A).max())
        np.testing.assert_allclose(V.T @ V, np.eye(A.shape[1]), atol=1e-13)


def test_lstsq_is_numpys_least_norm_solution() -> None:
    for A, b in problems(3):
        x, rank = dense.lstsq(A, b, 1e-12)
        ref, _, ref_rank, _ = np.linalg.lstsq(A, b, rcond=1e-12)
        assert rank == ref_rank
        np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-9 * abs(ref).max())


def test_descending_order_is_numpys_stable_argsort() -> None:
    """Ties in index order and NaN last, as ``np.argsort(-sv, kind="stable")``."""
    rng = np.random.default_rng(5)
    for _ in range(300):
        sv = rng.choice([0.0, 1.0, 2.0, np.nan, 0.5], size=int(rng.integers(0, 7)))
        np.testing.assert_array_equal(dense._descending(sv), np.argsort(-sv, kind="stable"))


def test_lstsq_into_writes_lstsq_into_a_buffer() -> None:
    for A, b in problems(6, 100):
        x = np.full(A.shape[1], np.nan)
        rank = dense.lstsq_into(A, b, 1e-12, 1e-9, x)
        ref, ref_rank = dense.lstsq(A, b, 1e-12, 1e-9)
        assert rank == ref_rank
        np.testing.assert_array_equal(x, ref)


def test_rank_matches_numpy() -> None:
    for A, _ in problems(4):
        tol = 1e-10 * abs(A).max()
        assert dense.rank(A, tol) == np.linalg.matrix_rank(A, tol=tol)


def test_solve_and_det_match_lapack() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 4, 5, 6):
        for _ in range(50):
            A = rng.normal(size=(n, n))
            b = rng.normal(size=n)
            x, ok = dense.solve(A, b)
            assert ok
            np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-9, atol=1e-12)
            assert dense.det(A) == pytest.approx(np.linalg.det(A), rel=1e-12, abs=1e-14)


def test_det_and_solve_is_det_then_solve_in_one_pair_of_buffers() -> None:
    """The volume of one matrix and the solve with another, as LAPACK gives them, and the
    bits of ``det`` and ``solve`` called apart (singular matrices included)."""
    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 4):
        for k in range(60):
            U, A = rng.normal(size=(n, n)), rng.normal(size=(n, n))
            if k % 3 == 0:
                A[-1] = 2.0 * A[0]  # singular: no solution reported
            b = rng.normal(size=n)
            volume, x, ok = dense.det_and_solve(U, A, b)
            assert volume == pytest.approx(np.linalg.det(U), rel=1e-12, abs=1e-14)
            x_ref, ok_ref = dense.solve(A, b)
            assert volume == dense.det(U)
            assert ok == ok_ref
            if n == 2 and k % 3 == 0:
                assert not ok  # an exactly zero pivot
            if ok:
                np.testing.assert_array_equal(x, x_ref)
            if k % 3 != 0:
                assert ok
                np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-8, atol=1e-10)


def test_solve_reports_a_singular_matrix() -> None:
    A = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]])
    assert not dense.solve(A, np.ones(3))[1]
    assert dense.det(A) == 0.0
    assert not dense.solve(np.zeros((2, 2)), np.ones(2))[1]


def test_nnls_matches_scipy() -> None:
    """Same residual as scipy's nnls (the optimum is unique in the residual); the solution
    itself where the problem has full column rank."""
    for A, b in problems(6):
        x, r = dense.nnls(A, b)
        ref, r_ref = scipy_nnls(A, b)
        assert np.all(x >= 0.0)
        scale = abs(A).max() * abs(b).max() + abs(b).max()
        assert r == pytest.approx(r_ref, abs=1e-10 * scale)
        assert r == pytest.approx(float(np.linalg.norm(A @ x - b)), abs=1e-12 * scale)
        if A.shape[0] >= A.shape[1] and np.linalg.matrix_rank(A) == A.shape[1]:
            np.testing.assert_allclose(x, ref, atol=1e-8 * (abs(ref).max() + 1.0))


def test_nnls_without_columns() -> None:
    x, r = dense.nnls(np.zeros((3, 0)), np.array([3.0, 4.0, 0.0]))
    assert x.shape == (0,) and r == 5.0


def test_nnls_is_unit_free() -> None:
    """Scaling the data by powers of two scales the solution exactly: no absolute
    tolerance decides which columns are used."""
    rng = np.random.default_rng(7)
    for _ in range(100):
        A, b = rng.normal(size=(3, 4)), rng.normal(size=3)
        x, _ = dense.nnls(A, b)
        for k in (2.0**-40, 2.0**40):
            xk, _ = dense.nnls(A, b * k)
            np.testing.assert_array_equal(xk, x * k)


def test_stale_kernel_cache_is_cleared(tmp_path) -> None:
    """Editing any compiled module clears the numba cache, wherever it is (cached callers
    would keep a callee's old code); unchanged sources keep it."""
    from grasp_env.compiled import drop_stale_cache

    def sources() -> list:
        return sorted(tmp_path.glob("*.py"))

    (tmp_path / "a.py").write_text("x = 1\n")
    cache = tmp_path / "elsewhere" / "cache"
    cache.mkdir(parents=True)
    (cache / "a.f-1.py311.nbi").write_text("index")
    (cache / "a.f-1.py311.1.nbc").write_text("code")
    assert drop_stale_cache(sources(), cache)  # no stamp yet: whatever is there is unknown
    assert not list(cache.glob("*.nb?"))
    (cache / "a.f-1.py311.nbi").write_text("index")
    assert not drop_stale_cache(sources(), cache)
    assert (cache / "a.f-1.py311.nbi").exists()
    (tmp_path / "b.py").write_text("y = 2\n")
    assert drop_stale_cache(sources(), cache)
    assert not (cache / "a.f-1.py311.nbi").exists()
    assert not drop_stale_cache(sources(), None)  # no cache folder: nothing to clear
