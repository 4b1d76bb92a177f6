#include "mapping/serial_blas.h"

#include <dlfcn.h>
#include <gtest/gtest.h>

namespace waymark {
namespace {

// In `waymark`, CHOLMOD (through Ceres) brings libgomp into the process. This test uses no
// solver, so the linker leaves Ceres out: libgomp is loaded here as CHOLMOD would load it. The
// count is set above 1 first so that the guard has work to do.
TEST(ScopedSerialLinearAlgebraTest, HoldsOpenMpToOneThreadAndRestores) {
  if (dlsym(RTLD_DEFAULT, "omp_set_num_threads") == nullptr) {
    ASSERT_NE(dlopen("libgomp.so.1", RTLD_NOW | RTLD_GLOBAL), nullptr) << dlerror();
  }
  const auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_num_threads"));
  ASSERT_NE(set, nullptr);
  set(3);
  ASSERT_EQ(ScopedSerialLinearAlgebra::OpenMpThreads(), 3);
  {
    const ScopedSerialLinearAlgebra serial;
    EXPECT_EQ(ScopedSerialLinearAlgebra::OpenMpThreads(), 1);
    if (ScopedSerialLinearAlgebra::OpenBlasThreads() > 0) {
      EXPECT_EQ(ScopedSerialLinearAlgebra::OpenBlasThreads(), 1);
    }
    {
      const ScopedSerialLinearAlgebra nested;  // already 1: nothing to restore
      EXPECT_EQ(ScopedSerialLinearAlgebra::OpenMpThreads(), 1);
    }
    EXPECT_EQ(ScopedSerialLinearAlgebra::OpenMpThreads(), 1);
  }
  EXPECT_EQ(ScopedSerialLinearAlgebra::OpenMpThreads(), 3);
}

}  // namespace
}  // namespace waymark
