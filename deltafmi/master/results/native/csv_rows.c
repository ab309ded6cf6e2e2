/* Rows of doubles as CSV text, each Real exactly as Python's repr() writes it, Integer and
 * Boolean columns as integers.
 *
 * repr() writes the shortest digits that read back to the same double (the closest of them
 * when several are that short), in fixed notation for decimal exponents -4 ... 15 and as
 * d.ddde+XX otherwise, with ".0" on integral values, "nan", "inf", "-0.0". It costs about
 * 0.7 us a number (David Gay's dtoa): 10 us a row of the flagship's results, a tenth of a
 * whole co-simulation step. The digits here come from Ulf Adams' Ryu algorithm (PLDI 2018:
 * shortest and correctly rounded, 64 x 128-bit products against tables of powers of five),
 * about ten times faster. The tables are computed exactly by the caller (Python integers, see
 * deltafmi/master/results.py) and handed over once.
 *
 * A sink (deltafmi_csv_sink_*) formats and writes blocks of rows on a thread of its own: the
 * master's C loop hands its blocks over and steps on, with no Python between a block and its
 * text (see the sink's section). Plain C, no Python.
 */
/* the oldest versions of what moved into libc in glibc 2.34, as in fixed_step.c */
#if defined(__x86_64__) && defined(__linux__)
__asm__(".symver pthread_create,pthread_create@GLIBC_2.2.5");
__asm__(".symver pthread_join,pthread_join@GLIBC_2.2.5");
#endif
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef unsigned __int128 uint128_t;

#define MANTISSA_BITS 52
#define EXPONENT_BITS 11
#define BIAS 1023
#define POW5_INV_BITCOUNT 125
#define POW5_BITCOUNT 125
#define POW5_INV_TABLE_SIZE 342
#define POW5_TABLE_SIZE 326

/* [i][0] low, [i][1] high 64 bits */
static const uint64_t (*pow5_inv_split)[2];
static const uint64_t (*pow5_split)[2];

__attribute__((visibility("default")))
void deltafmi_csv_tables(const uint64_t *inverse, const uint64_t *powers)
{
    pow5_inv_split = (const uint64_t(*)[2])inverse;
    pow5_split = (const uint64_t(*)[2])powers;
}

static inline uint32_t pow5bits(int32_t e) { return (uint32_t)(((e * 1217359) >> 19) + 1); }
static inline uint32_t log10_pow2(int32_t e) { return (uint32_t)((e * 78913) >> 18); }
static inline uint32_t log10_pow5(int32_t e) { return (uint32_t)((e * 732923) >> 20); }

static inline uint32_t pow5_factor(uint64_t value)
{
    uint32_t count = 0;
    for (;;) {
        uint64_t q = value / 5;
        if (value - 5 * q != 0) break;
        value = q;
        ++count;
    }
    return count;
}

static inline int multiple_of_pow5(uint64_t value, uint32_t p) { return pow5_factor(value) >= p; }
static inline int multiple_of_pow2(uint64_t value, uint32_t p) { return (value & ((1ull << p) - 1)) == 0; }

static inline uint64_t mul_shift(uint64_t m, const uint64_t *mul, int32_t j)
{
    uint128_t b0 = (uint128_t)m * mul[0];
    uint128_t b2 = (uint128_t)m * mul[1];
    return (uint64_t)(((b0 >> 64) + b2) >> (j - 64));
}

/* Ryu's d2d: the shortest decimal mantissa * 10^exponent that reads back as the double */
static void shortest(uint64_t ieee_mantissa, uint32_t ieee_exponent, uint64_t *digits, int32_t *exponent)
{
    int32_t e2;
    uint64_t m2;
    if (ieee_exponent == 0) {
        e2 = 1 - BIAS - MANTISSA_BITS - 2;
        m2 = ieee_mantissa;
    } else {
        e2 = (int32_t)ieee_exponent - BIAS - MANTISSA_BITS - 2;
        m2 = (1ull << MANTISSA_BITS) | ieee_mantissa;
    }
    const int accept_bounds = (m2 & 1) == 0;
    const uint64_t mv = 4 * m2;
    const uint32_t mm_shift = ieee_mantissa != 0 || ieee_exponent <= 1;
    uint64_t vr, vp, vm;
    int32_t e10;
    int vm_trailing_zeros = 0, vr_trailing_zeros = 0;
    if (e2 >= 0) {
        const uint32_t q = log10_pow2(e2) - (e2 > 3);
        e10 = (int32_t)q;
        const int32_t k = POW5_INV_BITCOUNT + (int32_t)pow5bits((int32_t)q) - 1;
        const int32_t i = -e2 + (int32_t)q + k;
        vr = mul_shift(4 * m2, pow5_inv_split[q], i);
        vp = mul_shift(4 * m2 + 2, pow5_inv_split[q], i);
        vm = mul_shift(4 * m2 - 1 - mm_shift, pow5_inv_split[q], i);
        if (q <= 21) {
            if (mv % 5 == 0)
                vr_trailing_zeros = multiple_of_pow5(mv, q);
            else if (accept_bounds)
                vm_trailing_zeros = multiple_of_pow5(mv - 1 - mm_shift, q);
            else
                vp -= multiple_of_pow5(mv + 2, q);
        }
    } else {
        const uint32_t q = log10_pow5(-e2) - (-e2 > 1);
        e10 = (int32_t)q + e2;
        const int32_t i = -e2 - (int32_t)q;
        const int32_t k = (int32_t)pow5bits(i) - POW5_BITCOUNT;
        const int32_t j = (int32_t)q - k;
        vr = mul_shift(4 * m2, pow5_split[i], j);
        vp = mul_shift(4 * m2 + 2, pow5_split[i], j);
        vm = mul_shift(4 * m2 - 1 - mm_shift, pow5_split[i], j);
        if (q <= 1) {
            vr_trailing_zeros = 1;
            if (accept_bounds)
                vm_trailing_zeros = mm_shift == 1;
            else
                --vp;
        } else if (q < 63) {
            vr_trailing_zeros = multiple_of_pow2(mv, q);
        }
    }
    int32_t removed = 0;
    uint8_t last_removed = 0;
    uint64_t output;
    if (vm_trailing_zeros || vr_trailing_zeros) {
        for (;;) {
            if (vp / 10 <= vm / 10) break;
            vm_trailing_zeros &= vm % 10 == 0;
            vr_trailing_zeros &= last_removed == 0;
            last_removed = (uint8_t)(vr % 10);
            vr /= 10;
            vp /= 10;
            vm /= 10;
            ++removed;
        }
        if (vm_trailing_zeros) {
            while (vm % 10 == 0) {
                vr_trailing_zeros &= last_removed == 0;
                last_removed = (uint8_t)(vr % 10);
                vr /= 10;
                vp /= 10;
                vm /= 10;
                ++removed;
            }
        }
        if (vr_trailing_zeros && last_removed == 5 && vr % 2 == 0) last_removed = 4; /* round half even */
        output = vr + ((vr == vm && (!accept_bounds || !vm_trailing_zeros)) || last_removed >= 5);
    } else {
        int round_up = 0;
        if (vp / 100 > vm / 100) {
            round_up = vr % 100 >= 50;
            vr /= 100;
            vp /= 100;
            vm /= 100;
            removed += 2;
            /* short outputs (0.001, 0.25): four digits a time while four can go; the loop below
             * would remove them one by one, its rounding set by the last, the highest of them */
            while (vp / 10000 > vm / 10000) {
                round_up = vr % 10000 >= 5000;
                vr /= 10000;
                vp /= 10000;
                vm /= 10000;
                removed += 4;
            }
        }
        for (;;) {
            if (vp / 10 <= vm / 10) break;
            round_up = vr % 10 >= 5;
            vr /= 10;
            vp /= 10;
            vm /= 10;
            ++removed;
        }
        output = vr + (vr == vm || round_up);
    }
    *digits = output;
    *exponent = e10 + removed;
}

/* "00" ... "99": two digits a division */
static const char DIGIT_PAIRS[200] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

/* 10^i, i < 20 */
static const uint64_t POWERS_OF_TEN[20] = {
    1ull, 10ull, 100ull, 1000ull, 10000ull, 100000ull, 1000000ull, 10000000ull, 100000000ull, 1000000000ull,
    10000000000ull, 100000000000ull, 1000000000000ull, 10000000000000ull, 100000000000000ull,
    1000000000000000ull, 10000000000000000ull, 100000000000000000ull, 1000000000000000000ull,
    10000000000000000000ull};

/* the number of decimal digits of v (> 0): from its bit length (1233 / 4096 just above
 * log10(2)), one more where v reaches the next power of ten */
static inline int decimal_length(uint64_t v)
{
    const int guess = ((64 - __builtin_clzll(v)) * 1233) >> 12;
    return guess + (v >= POWERS_OF_TEN[guess]);
}

/* "dddd": w (< 10000) as exactly four digits */
static inline void write_four(uint32_t w, char *out)
{
    memcpy(out, DIGIT_PAIRS + 2 * (w / 100), 2);
    memcpy(out + 2, DIGIT_PAIRS + 2 * (w % 100), 2);
}

/* v's nd decimal digits into out[0 .. nd - 1]: eight at a time while there are more, as two
 * groups of four that do not wait for one another, then two at a time */
static inline void write_digits(uint64_t v, char *out, int nd)
{
    char *end = out + nd;
    while (v >= 100000000) {
        const uint64_t q = v / 100000000;
        const uint32_t r = (uint32_t)(v - 100000000 * q);
        end -= 8;
        write_four(r / 10000, end);
        write_four(r % 10000, end + 4);
        v = q;
    }
    uint32_t w = (uint32_t)v;
    while (w >= 100) {
        const uint32_t q = w / 100;
        end -= 2;
        memcpy(end, DIGIT_PAIRS + 2 * (w - 100 * q), 2);
        w = q;
    }
    if (w >= 10) {
        end -= 2;
        memcpy(end, DIGIT_PAIRS + 2 * w, 2);
    } else {
        *--end = (char)('0' + w);
    }
}

/* Python's "%d" % int(x) for a double holding an integer in range (the buses' 32-bit ones) */
static int format_integer(double x, char *out)
{
    long long v = (long long)x;
    int n = 0;
    uint64_t magnitude = (uint64_t)v;
    if (v < 0) {
        out[n++] = '-';
        magnitude = 0 - magnitude;
    }
    const int nd = decimal_length(magnitude ? magnitude : 1);
    if (!magnitude) {
        out[n] = '0';
        return n + 1;
    }
    write_digits(magnitude, out + n, nd);
    return n + nd;
}

/* repr(x) into out (room for 24 chars, the longest repr: it may write up to there, past the
 * length it returns); returns its length. The digits are written once, where they end up:
 * write_digits fills from the right, so a point inside them is made by moving the digits before
 * it one place left. */
static int repr_double(double x, char *out)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    const int sign = (int)(bits >> 63);
    const uint64_t ieee_mantissa = bits & ((1ull << MANTISSA_BITS) - 1);
    const uint32_t ieee_exponent = (uint32_t)((bits >> MANTISSA_BITS) & ((1u << EXPONENT_BITS) - 1));
    int n = 0;
    if (ieee_exponent == (1u << EXPONENT_BITS) - 1) {
        if (ieee_mantissa) {
            memcpy(out, "nan", 3);
            return 3;
        }
        if (sign) out[n++] = '-';
        memcpy(out + n, "inf", 3);
        return n + 3;
    }
    if (sign) out[n++] = '-';
    if (ieee_exponent == 0 && ieee_mantissa == 0) {
        memcpy(out + n, "0.0", 3);
        return n + 3;
    }
    uint64_t mantissa;
    int32_t e10;
    shortest(ieee_mantissa, ieee_exponent, &mantissa, &e10);
    const int nd = decimal_length(mantissa);
    const int exponent = e10 + nd - 1; /* of the first digit */
    char *p = out + n;
    if (exponent >= -4 && exponent < 16) {
        if (exponent < 0) { /* 0.000ddd */
            memcpy(p, "0.0000", 6);
            p += 1 - exponent;
            write_digits(mantissa, p, nd);
            return (int)(p - out) + nd;
        }
        if (nd <= exponent + 1) { /* integral: ddd000.0 (at most 16 digits) */
            memset(p, '0', 16);
            write_digits(mantissa, p, nd);
            p += exponent + 1;
            memcpy(p, ".0", 2);
            return (int)(p - out) + 2;
        }
        write_digits(mantissa, p + 1, nd); /* ddd.ddd */
        for (int i = 0; i <= exponent; i++) p[i] = p[i + 1];
        p[exponent + 1] = '.';
        return n + nd + 1;
    }
    write_digits(mantissa, p + 1, nd); /* d.ddde+XX */
    p[0] = p[1];
    if (nd > 1) {
        p[1] = '.';
        p += nd + 1;
    } else {
        p += 1;
    }
    *p++ = 'e';
    *p++ = exponent < 0 ? '-' : '+';
    int e = exponent < 0 ? -exponent : exponent;
    if (e >= 100) *p++ = (char)('0' + e / 100);
    *p++ = (char)('0' + e / 10 % 10);
    *p++ = (char)('0' + e % 10);
    return (int)(p - out);
}

/* n_rows rows of `width` doubles (row-major) as lines "v,v,...\n" into out (room for
 * n_rows * width * 33 + 32 chars: a value and its comma take at most 25, and up to 32 are
 * written where a value starts); integer[j] != 0 writes column j as an integer (truncated, as
 * Python's "%d" does; the master's Integer and Boolean buses hold 32-bit integers).
 * A value with the bits of the one above it in its column is copied from that one's text.
 * Returns the number of chars written. */
__attribute__((visibility("default")))
size_t deltafmi_csv_rows(const double *rows, long n_rows, long width, const int *integer, char *out)
{
    size_t n = 0;
    size_t *above = n_rows > 1 ? malloc((size_t)width * 2 * sizeof *above) : NULL; /* text start, length */
    for (long i = 0; i < n_rows; i++) {
        const double *row = rows + i * width;
        const double *previous = row - width;
        for (long j = 0; j < width; j++) {
            if (j) out[n++] = ',';
            size_t length;
            if (above && i && memcmp(&row[j], &previous[j], sizeof(double)) == 0) {
                length = above[2 * j + 1];
                /* a fixed 32 bytes (a text is at most 24: the rest is written over next), copied
                 * inline instead of a call; all read before any is written: in a narrow row the
                 * two may overlap */
                char text[32];
                memcpy(text, out + above[2 * j], 32);
                memcpy(out + n, text, 32);
            } else if (integer[j]) {
                length = (size_t)format_integer(row[j], out + n);
            } else {
                length = (size_t)repr_double(row[j], out + n);
            }
            if (above) {
                above[2 * j] = n;
                above[2 * j + 1] = length;
            }
            n += length;
        }
        out[n++] = '\n';
    }
    free(above);
    return n;
}

/* --- the sink -------------------------------------------------------------------------------
 * Blocks of rows queued by deltafmi_csv_sink_put are formatted (deltafmi_csv_rows, `chunk` rows at
 * a time into the sink's buffer) and written to the file descriptor, in the order queued, by the
 * sink's thread. The caller keeps each block's memory as it is until the sink has taken it
 * (deltafmi_csv_sink_taken counts the blocks done). A write that fails (a full disk, a quota, a
 * file size limit) cuts the file back to the end of the last whole row, as CsvWriter does in
 * Python, and the sink writes nothing more; deltafmi_csv_sink_wait reports the whole rows and
 * bytes written, the time of the last whole row and the error. */
enum { SINK_QUEUE = 64 };

typedef struct {
    long long size;   /* bytes written by the sink (whole rows only) */
    long rows;        /* rows written */
    double last_time; /* of the last row written (NaN: none) */
    int error;        /* errno of the write that failed (0: none) */
} SinkReport;

typedef struct {
    int fd;
    long width, chunk;
    int *integer;
    char *text;
    const double *blocks[SINK_QUEUE];
    long lengths[SINK_QUEUE];
    long queued, taken; /* blocks put, blocks done (the queue: [taken, queued) mod SINK_QUEUE) */
    int quit;
    SinkReport report;
    pthread_mutex_t lock;
    pthread_cond_t more, done;
    pthread_t thread;
} Sink;

/* text[0, size) to the file; on a failed write the file cut back to its last whole row, the
 * rows (of `width` doubles from `rows`) counted up to there. Returns 0, or errno. */
static int sink_write(Sink *s, const char *text, size_t size, const double *rows)
{
    size_t written = 0;
    while (written < size) {
        ssize_t n = write(s->fd, text + written, size - written);
        if (n >= 0) {
            written += (size_t)n;
            continue;
        }
        if (errno == EINTR) continue;
        int error = errno;
        long whole = 0;
        size_t keep = 0;
        for (size_t i = 0; i < written; i++) {
            if (text[i] == '\n') {
                whole++;
                keep = i + 1;
            }
        }
        off_t end = lseek(s->fd, 0, SEEK_CUR); /* where the part written ends */
        if (end >= 0) (void)!ftruncate(s->fd, end - (off_t)written + (off_t)keep); /* frees space: cannot fail for lack of it */
        s->report.size += (long long)keep;
        s->report.rows += whole;
        if (whole) s->report.last_time = rows[(whole - 1) * s->width];
        return error;
    }
    s->report.size += (long long)size;
    return 0;
}

static void *sink_thread(void *arg)
{
    Sink *s = arg;
    pthread_mutex_lock(&s->lock);
    for (;;) {
        while (s->taken == s->queued && !s->quit) pthread_cond_wait(&s->more, &s->lock);
        if (s->taken == s->queued) break; /* quit, everything written */
        const double *rows = s->blocks[s->taken % SINK_QUEUE];
        long n = s->lengths[s->taken % SINK_QUEUE];
        int failed = s->report.error != 0;
        pthread_mutex_unlock(&s->lock);
        for (long done = 0; done < n && !failed; done += s->chunk) {
            long take = n - done < s->chunk ? n - done : s->chunk;
            const double *part = rows + done * s->width;
            size_t size = deltafmi_csv_rows(part, take, s->width, s->integer, s->text);
            int error = sink_write(s, s->text, size, part);
            pthread_mutex_lock(&s->lock);
            if (error) {
                s->report.error = error;
                failed = 1;
            } else {
                s->report.rows += take;
                s->report.last_time = part[(take - 1) * s->width];
            }
            pthread_mutex_unlock(&s->lock);
        }
        pthread_mutex_lock(&s->lock);
        s->taken++;
        pthread_cond_broadcast(&s->done);
    }
    pthread_mutex_unlock(&s->lock);
    return NULL;
}

/* A sink writing rows of `width` doubles (integer[j] != 0: column j as an integer) to fd,
 * formatted `chunk` rows at a time; NULL when it cannot be made (no memory, no thread). */
__attribute__((visibility("default")))
Sink *deltafmi_csv_sink_open(int fd, long width, const int *integer, long chunk)
{
    Sink *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->fd = fd;
    s->width = width;
    s->chunk = chunk > 0 ? chunk : 1;
    s->integer = malloc((size_t)width * sizeof *s->integer);
    s->text = malloc((size_t)(s->chunk * width * 33 + 32)); /* deltafmi_csv_rows' room */
    s->report.last_time = NAN;
    if (!s->integer || !s->text) goto failed;
    memcpy(s->integer, integer, (size_t)width * sizeof *s->integer);
    pthread_mutex_init(&s->lock, NULL);
    pthread_cond_init(&s->more, NULL);
    pthread_cond_init(&s->done, NULL);
    if (pthread_create(&s->thread, NULL, sink_thread, s) != 0) {
        pthread_cond_destroy(&s->done);
        pthread_cond_destroy(&s->more);
        pthread_mutex_destroy(&s->lock);
        goto failed;
    }
    return s;
failed:
    free(s->integer);
    free(s->text);
    free(s);
    return NULL;
}

/* Queue n rows (row-major, `width` doubles each) at `rows`, kept by the caller until taken;
 * waits while the queue is full. Returns the number of blocks queued so far. */
__attribute__((visibility("default")))
long deltafmi_csv_sink_put(Sink *s, const double *rows, long n)
{
    pthread_mutex_lock(&s->lock);
    while (s->queued - s->taken == SINK_QUEUE) pthread_cond_wait(&s->done, &s->lock);
    s->blocks[s->queued % SINK_QUEUE] = rows;
    s->lengths[s->queued % SINK_QUEUE] = n;
    long queued = ++s->queued;
    pthread_cond_signal(&s->more);
    pthread_mutex_unlock(&s->lock);
    return queued;
}

/* The blocks the sink is done with (written, or dropped after a failure). */
__attribute__((visibility("default")))
long deltafmi_csv_sink_taken(Sink *s)
{
    pthread_mutex_lock(&s->lock);
    long taken = s->taken;
    pthread_mutex_unlock(&s->lock);
    return taken;
}

/* The errno of the write that failed (0: none so far). */
__attribute__((visibility("default")))
int deltafmi_csv_sink_failed(Sink *s)
{
    pthread_mutex_lock(&s->lock);
    int error = s->report.error;
    pthread_mutex_unlock(&s->lock);
    return error;
}

/* Wait until every block queued is done; what the sink has written so far into *report. */
__attribute__((visibility("default")))
void deltafmi_csv_sink_wait(Sink *s, SinkReport *report)
{
    pthread_mutex_lock(&s->lock);
    while (s->taken != s->queued) pthread_cond_wait(&s->done, &s->lock);
    *report = s->report;
    pthread_mutex_unlock(&s->lock);
}

/* Write what is queued, end the thread and free the sink (the file descriptor stays open). */
__attribute__((visibility("default")))
void deltafmi_csv_sink_close(Sink *s)
{
    pthread_mutex_lock(&s->lock);
    s->quit = 1;
    pthread_cond_signal(&s->more);
    pthread_mutex_unlock(&s->lock);
    pthread_join(s->thread, NULL);
    pthread_cond_destroy(&s->done);
    pthread_cond_destroy(&s->more);
    pthread_mutex_destroy(&s->lock);
    free(s->integer);
    free(s->text);
    free(s);
}
