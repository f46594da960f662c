// A minimal test harness for the engine's C++ unit tests (one executable per source
// file, run by ctest): CHECK(cond), CHECK_NEAR(a, b, tol), and TEST(name) { ... }
// blocks collected into main by RBSIM_TEST_MAIN.
#pragma once

#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace rbsim::test {

struct Case {
  const char* name;
  void (*fn)();
};
inline std::vector<Case>& cases() {
  static std::vector<Case> all;
  return all;
}
inline int& failures() {
  static int n = 0;
  return n;
}
struct Register {
  Register(const char* name, void (*fn)()) { cases().push_back({name, fn}); }
};

inline void fail(const char* file, int line, const std::string& what) {
  std::printf("%s:%d: FAILED: %s\n", file, line, what.c_str());
  ++failures();
}

}  // namespace rbsim::test

#define TEST(name)                                                  \
  static void name();                                               \
  static ::rbsim::test::Register register_##name(#name, &name);     \
  static void name()

#define CHECK(cond) \
  do {              \
    if (!(cond)) ::rbsim::test::fail(__FILE__, __LINE__, #cond); \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                                          \
  do {                                                                                 \
    const double va_ = (a), vb_ = (b);                                                 \
    if (!(std::fabs(va_ - vb_) <= (tol)))                                              \
      ::rbsim::test::fail(__FILE__, __LINE__,                                          \
                          std::string(#a " = ") + std::to_string(va_) + ", " #b " = " + \
                              std::to_string(vb_) + " (tolerance " #tol ")");          \
  } while (0)

#define RBSIM_TEST_MAIN                                                         \
  int main() {                                                                  \
    for (const auto& c : ::rbsim::test::cases()) {                              \
      int before = ::rbsim::test::failures();                                   \
      c.fn();                                                                   \
      std::printf("%s %s\n", ::rbsim::test::failures() == before ? "ok  " : "FAIL", c.name); \
    }                                                                           \
    return ::rbsim::test::failures() == 0 ? 0 : 1;                              \
  }
