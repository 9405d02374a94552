/*
 * simrand: the one seeded pseudo-random generator of the simulations (plant
 * noise and parameter perturbations, closed-loop start positions, servo-bus
 * noise on the bench and in unit tests). splitmix64 over caller-owned state:
 * the same seed gives the same run on every machine. Host code only, never
 * the firmware.
 */
#ifndef HALLHOME_SIMRAND_H
#define HALLHOME_SIMRAND_H

#include <stdint.h>

/* Next 64 random bits; advances *state. */
static inline uint64_t simrand_next(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1), 53 bits. */
static inline double simrand_unit(uint64_t *state)
{
    return (double)(simrand_next(state) >> 11) / 9007199254740992.0;
}

#endif /* HALLHOME_SIMRAND_H */
