// CB_VECTOR_CLONES: a function compiled three times, for AVX-512, AVX2 and any x86-64, the body picked when
// the program loads by the processor it runs on. For the bake's loops that run across independent lanes
// (points, axes), so that they take 8 or 16 at a step where the baseline build takes 2 or 4. Every lane does
// the same operations in the same order in each body (-ffp-contract=off: no fused multiply-adds), so the
// results, and the assets, do not depend on the processor.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__)
#define CB_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CB_VECTOR_CLONES
#endif
