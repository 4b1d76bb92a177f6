#include "mapping/serial_blas.h"

#include <dlfcn.h>

namespace waymark {
namespace {

using SetThreads = void (*)(int);
using GetThreads = int (*)();

template <typename F>
F Lookup(const char* name) {
  // RTLD_DEFAULT: the symbol of whichever loaded library defines it (libgomp through CHOLMOD,
  // libopenblas when it is the selected libblas.so.3); null when none does.
  return reinterpret_cast<F>(dlsym(RTLD_DEFAULT, name));
}

}  // namespace

int ScopedSerialLinearAlgebra::OpenMpThreads() {
  const auto get = Lookup<GetThreads>("omp_get_max_threads");
  return get != nullptr ? get() : 0;
}

int ScopedSerialLinearAlgebra::OpenBlasThreads() {
  const auto get = Lookup<GetThreads>("openblas_get_num_threads");
  return get != nullptr ? get() : 0;
}

ScopedSerialLinearAlgebra::ScopedSerialLinearAlgebra() {
  if (const auto set = Lookup<SetThreads>("omp_set_num_threads")) {
    omp_threads_ = OpenMpThreads();
    if (omp_threads_ != 1) set(1);
  }
  if (const auto set = Lookup<SetThreads>("openblas_set_num_threads")) {
    openblas_threads_ = OpenBlasThreads();
    if (openblas_threads_ != 1) set(1);
  }
}

ScopedSerialLinearAlgebra::~ScopedSerialLinearAlgebra() {
  if (omp_threads_ > 1) {
    if (const auto set = Lookup<SetThreads>("omp_set_num_threads")) set(omp_threads_);
  }
  if (openblas_threads_ > 1) {
    if (const auto set = Lookup<SetThreads>("openblas_set_num_threads")) set(openblas_threads_);
  }
}

}  // namespace waymark
