// Compiler-specific syntax behind portable names, so that the engine builds
// with g++, clang (Linux and Apple) and MSVC. Each macro degrades to nothing
// (or plain `inline`) where a compiler has no equivalent: they change speed,
// never results.
#pragma once

// A pointer argument that aliases no other pointer argument (lets the
// compiler vectorise loops over several arrays).
#if defined(_MSC_VER)
#define QOGI_RESTRICT __restrict
#elif defined(__GNUC__) || defined(__clang__)
#define QOGI_RESTRICT __restrict__
#else
#define QOGI_RESTRICT
#endif

// An inline function the optimiser must inline (small kernels in hot loops).
#if defined(_MSC_VER)
#define QOGI_ALWAYS_INLINE __forceinline
#elif defined(__GNUC__) || defined(__clang__)
#define QOGI_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define QOGI_ALWAYS_INLINE inline
#endif

// Function multi-versioning: one clone per listed target, chosen at load time
// (GNU ifunc). g++ and clang >= 14 on x86-64 Linux; elsewhere the default build
// is used.
#if defined(__x86_64__) && defined(__linux__) && \
    ((defined(__GNUC__) && !defined(__clang__)) || (defined(__clang__) && __clang_major__ >= 14))
#define QOGI_TARGET_CLONES(...) __attribute__((target_clones(__VA_ARGS__)))
#else
#define QOGI_TARGET_CLONES(...)
#endif
