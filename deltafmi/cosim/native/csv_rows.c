/* Rows of doubles as CSV text, each Real exactly as Python's repr() writes it (the shortest
 * digits that read back to the same double, fixed notation for decimal exponents -4 ... 15,
 * else d.ddde+XX; "1.0", "-0.0", "nan", "inf"), Integer and Boolean columns as integers.
 *
 * Python's repr costs about 1 us a number on a slow machine, 15 us a row of the flagship's
 * results; this writes a row in a fraction of that. The shortest digits come from the C
 * library's correctly rounded printf at 15, 16 and 17 significant digits (the first that reads
 * back through strtod), which is what repr gives: a string of at most 15 digits that reads back
 * is the 15-digit rounding with its trailing zeros dropped (for normal numbers; subnormals,
 * with fewer significant bits, try from 1 digit up). Plain C, no Python.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Near a power of two a double's rounding interval is lopsided: the nearest 16 digits may miss
 * it while their neighbour one unit in the last digit away reads back. Writes that neighbour
 * as "[-]d.ddde[+-]X" into buf and returns 1, or returns 0 when neither reads back. */
static int shortest_neighbour(double x, char *buf, size_t size)
{
    char nearest[40];
    snprintf(nearest, sizeof nearest, "%.15e", fabs(x));
    long long m = 0;
    const char *p = nearest;
    for (; *p && *p != 'e'; p++)
        if (*p != '.') m = 10 * m + (*p - '0');
    int exponent = atoi(p + 1);
    for (int step = -1; step <= 1; step += 2) {
        char candidate[48], digits[24];
        snprintf(candidate, sizeof candidate, "%s%llde%d", x < 0 ? "-" : "", m + step, exponent - 15);
        if (strtod(candidate, NULL) != x) continue;
        int nd = snprintf(digits, sizeof digits, "%lld", m + step);
        snprintf(buf, size, "%s%c.%se%d", x < 0 ? "-" : "", digits[0], digits + 1, exponent + nd - 16);
        return 1;
    }
    return 0;
}

/* repr(x) into out (room for 32 chars); returns its length */
static int repr_double(double x, char *out)
{
    if (isnan(x)) { memcpy(out, "nan", 3); return 3; }
    if (isinf(x)) {
        if (x < 0) { memcpy(out, "-inf", 4); return 4; }
        memcpy(out, "inf", 3); return 3;
    }
    char buf[40];
    /* a subnormal has fewer significant bits: its shortest digits may be fewer than 15 */
    int precision = fabs(x) < DBL_MIN && x != 0.0 ? 1 : 15;
    for (; precision < 17; precision++) {
        snprintf(buf, sizeof buf, "%.*e", precision - 1, x);
        if (strtod(buf, NULL) == x) break;
    }
    if (precision == 17 && !shortest_neighbour(x, buf, sizeof buf)) snprintf(buf, sizeof buf, "%.*e", 16, x);
    /* buf: [-]d.ddddde[+-]XX: split into sign, digits (trailing zeros dropped), exponent */
    const char *p = buf;
    int n = 0;
    if (*p == '-') { out[n++] = '-'; p++; }
    char digits[20];
    int nd = 0;
    for (; *p && *p != 'e'; p++)
        if (*p != '.') digits[nd++] = *p;
    int exponent = atoi(p + 1);
    while (nd > 1 && digits[nd - 1] == '0') nd--;
    if (exponent >= -4 && exponent < 16) {
        if (exponent < 0) {
            out[n++] = '0';
            out[n++] = '.';
            for (int i = -1; i > exponent; i--) out[n++] = '0';
            memcpy(out + n, digits, nd);
            n += nd;
        } else {
            for (int i = 0; i <= exponent; i++) out[n++] = i < nd ? digits[i] : '0';
            out[n++] = '.';
            if (nd > exponent + 1) {
                memcpy(out + n, digits + exponent + 1, nd - exponent - 1);
                n += nd - exponent - 1;
            } else {
                out[n++] = '0';
            }
        }
        return n;
    }
    out[n++] = digits[0];
    if (nd > 1) {
        out[n++] = '.';
        memcpy(out + n, digits + 1, nd - 1);
        n += nd - 1;
    }
    return n + sprintf(out + n, "e%c%02d", exponent < 0 ? '-' : '+', abs(exponent));
}

/* n_rows rows of `width` doubles (row-major) as lines "v,v,...\n" into out (room for
 * n_rows * width * 32 chars); integer[j] != 0 writes column j as an integer (truncated, as
 * Python's "%d" does). Returns the number of chars written. */
__attribute__((visibility("default")))
size_t deltafmi_csv_rows(const double *rows, long n_rows, long width, const int *integer, char *out)
{
    size_t n = 0;
    for (long i = 0; i < n_rows; i++) {
        const double *row = rows + i * width;
        for (long j = 0; j < width; j++) {
            if (j) out[n++] = ',';
            if (integer[j])
                n += (size_t)sprintf(out + n, "%lld", (long long)row[j]);
            else
                n += (size_t)repr_double(row[j], out + n);
        }
        out[n++] = '\n';
    }
    return n;
}
