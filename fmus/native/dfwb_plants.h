/* dfwb_plants.h - the plants of the C core and their parameter orders, written from their tables
 * (fmus/table.py) by `python -m dfwb.build_fmus.plant_header`; do not edit. */
#ifndef DFWB_PLANTS_H
#define DFWB_PLANTS_H

/* The plants' kinds (a state's header names its kind: plants are appended, never renumbered). */
#define DFWB_PLANT_FRICTION 1
#define DFWB_PLANT_BACKLASH 2
#define DFWB_PLANT_STATIC_BACKLASH 3

/* X(kind, name) for every plant: plant name defines dfwb_<name>_class in its own file. */
#define DFWB_PLANTS(X) \
    X(DFWB_PLANT_FRICTION, friction) \
    X(DFWB_PLANT_BACKLASH, backlash) \
    X(DFWB_PLANT_STATIC_BACKLASH, static_backlash)

/* dfwb_plant_new, the friction: {M, B, Fc, Fs, Dv, F, omega, phi, x0, v0, f, harmonics} */
#define DFWB_FRICTION_PARAMS 12
#define DFWB_FRICTION_M         0
#define DFWB_FRICTION_B         1
#define DFWB_FRICTION_Fc        2
#define DFWB_FRICTION_Fs        3
#define DFWB_FRICTION_Dv        4
#define DFWB_FRICTION_F         5
#define DFWB_FRICTION_omega     6
#define DFWB_FRICTION_phi       7
#define DFWB_FRICTION_x0        8
#define DFWB_FRICTION_v0        9
#define DFWB_FRICTION_f         10
#define DFWB_FRICTION_harmonics 11

/* dfwb_loop_new, the friction loop: {M, B, Fc, Fs, Dv, x0, v0} */
#define DFWB_LOOP_FRICTION_PARAMS 7
#define DFWB_FRICTION_LOOP_M  0
#define DFWB_FRICTION_LOOP_B  1
#define DFWB_FRICTION_LOOP_Fc 2
#define DFWB_FRICTION_LOOP_Fs 3
#define DFWB_FRICTION_LOOP_Dv 4
#define DFWB_FRICTION_LOOP_x0 5
#define DFWB_FRICTION_LOOP_v0 6

/* dfwb_plant_new, the backlash: {M1, M2, h, eps, F, omega, phi, x1_0, v1_0, v2_0, gap0, f, harmonics} */
#define DFWB_BACKLASH_PARAMS 13
#define DFWB_BACKLASH_M1        0
#define DFWB_BACKLASH_M2        1
#define DFWB_BACKLASH_h         2
#define DFWB_BACKLASH_eps       3
#define DFWB_BACKLASH_F         4
#define DFWB_BACKLASH_omega     5
#define DFWB_BACKLASH_phi       6
#define DFWB_BACKLASH_x1_0      7
#define DFWB_BACKLASH_v1_0      8
#define DFWB_BACKLASH_v2_0      9
#define DFWB_BACKLASH_gap0      10
#define DFWB_BACKLASH_f         11
#define DFWB_BACKLASH_harmonics 12

/* dfwb_loop_new, the backlash loop: {M1, M2, h, eps, x1_0, v1_0, v2_0, gap0} */
#define DFWB_LOOP_BACKLASH_PARAMS 8
#define DFWB_BACKLASH_LOOP_M1   0
#define DFWB_BACKLASH_LOOP_M2   1
#define DFWB_BACKLASH_LOOP_h    2
#define DFWB_BACKLASH_LOOP_eps  3
#define DFWB_BACKLASH_LOOP_x1_0 4
#define DFWB_BACKLASH_LOOP_v1_0 5
#define DFWB_BACKLASH_LOOP_v2_0 6
#define DFWB_BACKLASH_LOOP_gap0 7

/* dfwb_plant_new, the static backlash: {M, k, h, F, omega, phi, x0, v0, f, harmonics} */
#define DFWB_STATIC_BACKLASH_PARAMS 10
#define DFWB_STATIC_BACKLASH_M         0
#define DFWB_STATIC_BACKLASH_k         1
#define DFWB_STATIC_BACKLASH_h         2
#define DFWB_STATIC_BACKLASH_F         3
#define DFWB_STATIC_BACKLASH_omega     4
#define DFWB_STATIC_BACKLASH_phi       5
#define DFWB_STATIC_BACKLASH_x0        6
#define DFWB_STATIC_BACKLASH_v0        7
#define DFWB_STATIC_BACKLASH_f         8
#define DFWB_STATIC_BACKLASH_harmonics 9

/* dfwb_loop_new, the static backlash loop: {M, k, h, x0, v0} */
#define DFWB_LOOP_STATIC_BACKLASH_PARAMS 5
#define DFWB_STATIC_BACKLASH_LOOP_M  0
#define DFWB_STATIC_BACKLASH_LOOP_k  1
#define DFWB_STATIC_BACKLASH_LOOP_h  2
#define DFWB_STATIC_BACKLASH_LOOP_x0 3
#define DFWB_STATIC_BACKLASH_LOOP_v0 4

#endif
