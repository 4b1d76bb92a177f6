// Holds the dense linear algebra under the sparse solvers to one thread while a map builds.
#pragma once

namespace waymark {

// CHOLMOD (Ceres' SUITE_SPARSE solver) factors its supernodes through BLAS/LAPACK and OpenMP.
// With several threads there, the order of floating-point sums depends on the schedule, so a map
// could differ in its last bits from run to run (TagSLAM test6 with a per-frame camera wiggle:
// up to 1.3e-16 m; identical with OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1). The map must be
// the same at any load (docs/mapping.md, "Determinism"). While an object of this class lives,
// the calling thread's OpenMP thread count is 1 and, when the BLAS that Debian's alternatives
// selected is OpenBLAS, so is OpenBLAS's; the destructor restores both. The libraries are
// looked up at run time (dlsym), so nothing is linked that the process does not load anyway:
// with ATLAS or the reference BLAS (serial) only OpenMP is held. OpenBLAS's count is
// process-wide: two map builds at once in one process share it (both want 1).
class ScopedSerialLinearAlgebra {
 public:
  ScopedSerialLinearAlgebra();
  ~ScopedSerialLinearAlgebra();
  ScopedSerialLinearAlgebra(const ScopedSerialLinearAlgebra&) = delete;
  ScopedSerialLinearAlgebra& operator=(const ScopedSerialLinearAlgebra&) = delete;

  // The OpenMP and OpenBLAS thread counts in force now (0: the library is not loaded).
  static int OpenMpThreads();
  static int OpenBlasThreads();

 private:
  int omp_threads_ = 0;       // the count to restore; 0: not changed
  int openblas_threads_ = 0;  // likewise
};

}  // namespace waymark
