import torch

from models.geometry.small_linalg import adjugate3, solve_sym3, sym3_quadratic_form, sym3_smallest_eigenvalue_estimate


def _random_spd(n: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    A = torch.randn(n, 3, 3, generator=g, dtype=torch.float64)
    return A @ A.transpose(1, 2) + 0.1 * torch.eye(3, dtype=torch.float64)


def _entries(H: torch.Tensor) -> list[torch.Tensor]:
    return [H[:, 0, 0], H[:, 1, 1], H[:, 2, 2], H[:, 0, 1], H[:, 0, 2], H[:, 1, 2]]


def test_solve_sym3_matches_linalg_solve():
    H = _random_spd(1000)
    b = torch.randn(1000, 3, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    x, det = solve_sym3(_entries(H), b.unbind(-1))
    torch.testing.assert_close(torch.stack(x, -1), torch.linalg.solve(H, b), rtol=1e-9, atol=1e-9)
    torch.testing.assert_close(det, torch.linalg.det(H))


def test_adjugate_is_det_times_inverse():
    A = torch.randn(100, 3, 3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    adj, det = adjugate3(tuple(tuple(A[:, r, c] for c in range(3)) for r in range(3)))
    adj_t = torch.stack([torch.stack(row, -1) for row in adj], -2)
    torch.testing.assert_close(adj_t, torch.linalg.det(A)[:, None, None] * torch.linalg.inv(A))
    torch.testing.assert_close(det, torch.linalg.det(A))


def test_quadratic_form_and_smallest_eigenvalue():
    H = _random_spd(100)
    v = torch.randn(100, 3, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    torch.testing.assert_close(sym3_quadratic_form(_entries(H), v.unbind(-1)), torch.einsum("bi,bij,bj->b", v, H, v))
    # Nearly singular: one tiny eigenvalue is estimated well.
    Q, _ = torch.linalg.qr(torch.randn(100, 3, 3, generator=torch.Generator().manual_seed(4), dtype=torch.float64))
    lam = torch.tensor([1e-6, 1.0, 2.0], dtype=torch.float64)
    H = Q @ torch.diag(lam) @ Q.transpose(1, 2)
    est = sym3_smallest_eigenvalue_estimate(_entries(H), torch.linalg.det(H))
    torch.testing.assert_close(est, torch.full((100,), 1e-6, dtype=torch.float64), rtol=1e-5, atol=0)
