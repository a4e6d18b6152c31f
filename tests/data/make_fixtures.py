"""The results files the tests read, frozen: copies of the committed results/ files of commit
c2e6847936cdeac7581c192a1e71fde8e2f0bdd5.

Tests read only files they own (tests/data, or computed in the test): results/ is the published record, which
`bash scripts/hz.sh main` and `bash scripts/hz.sh paper` rewrite (on another number of ranks, with other round-off:
the branch of `hz.sh main` on 2 ranks differs from the committed one by 1.6e-9 in u, enough to move a residual the
tests bound at 1e-9). These copies keep each test's inputs consistent with each other (the refined waves were
refined from this branch, the Floquet records computed from them).

Run once from the repository's root (it needs git):  python tests/data/make_fixtures.py
"""
import os
import subprocess

COMMIT = "c2e6847936cdeac7581c192a1e71fde8e2f0bdd5"
FILES = ("branch_alpha1.5.npz", "refined_N100.npz", "floquet_N100.npz", "compacton_stability.npz", "wave.npz",
         "stability_boundary_alpha2_N100.npz", "stability_boundary_alpha1.5_N100.npz", "precompression_map.npz",
         "precompression_map.md", "precompression_map_dimer0.4.npz", "precompression_map_dimer0.4.md",
         "precompression_map_dimer0.7.npz", "precompression_map_dimer0.7.md", "boundary_in_q_alpha1.5.npz")
HERE = os.path.dirname(os.path.abspath(__file__))

if __name__ == "__main__":
    for name in FILES:
        data = subprocess.run(["git", "show", f"{COMMIT}:results/{name}"], check=True, capture_output=True).stdout
        with open(os.path.join(HERE, name), "wb") as f:
            f.write(data)
        print(f"tests/data/{name}: {len(data)} bytes")
