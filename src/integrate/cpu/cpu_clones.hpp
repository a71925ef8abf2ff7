// Function multiversioning for the CPU pair loops: one binary, the widest vectors the CPU has.
// BGK_CPU_CLONES on the function that holds the loops (GCC compiles it for AVX-512, AVX2 and
// baseline x86-64 and picks one at load time); BGK_INLINE_INTO_CLONES on its helpers, so that
// each clone gets its own copy of them compiled for its target. Each clone evaluates the same
// float expressions (no FMA contraction: the library builds with -ffp-contract=off), so results
// do not depend on the clone. Shared by the CPU back end and the pair-evaluation roofline
// benchmark (bench/roofline_kernel.cpp), which must be compiled the same way.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define BGK_CPU_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#define BGK_INLINE_INTO_CLONES [[gnu::always_inline]] inline
#else
#define BGK_CPU_CLONES
#define BGK_INLINE_INTO_CLONES inline
#endif
