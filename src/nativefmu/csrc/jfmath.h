/* jfmath.h: the transcendental functions of the native FMUs, with the same bits on
 * every platform (see jfmath.c). */
#ifndef JFMATH_H
#define JFMATH_H

double jm_sin(double x);
double jm_cos(double x);
double jm_tan(double x);
double jm_exp(double x);
double jm_expm1(double x);
double jm_log(double x);
double jm_log1p(double x);
/* the least integer s with 2^s >= v, for finite v > 0 (ceil(log2(v)) exactly) */
int jm_ceil_log2(double v);

#endif
