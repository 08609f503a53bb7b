/* The line writer of prs3_post.fixed.render_rows, in C (loaded with ctypes by prs3_post.native).
 *
 * Writes the same bytes as the numpy writer of prs3_post/fixed.py (a test compares the two on
 * random columns): rows of words, each word a prefix and a fixed-decimal number given as the
 * integer of its printed digits (-12.3457 with 4 decimals is -123457), or one text of a few
 * chosen per row (G0/G1, false/true); the words present on a row joined by one separator byte,
 * then the line ending. Cells whose text could not be made from an integer (nan, inf, too large)
 * are given as text ("overrides", sorted by row then column), written after the prefix.
 *
 * Plain C with no Python API: ctypes releases the GIL for the call, so a second thread can
 * format one chunk while the first reads and solves the next.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

/* The version of the library's functions and their arguments: prs3_post/native.py loads a library
 * only when it says the version that module was written for (an editable install whose csrc/ changed
 * since it was built falls back to numpy instead of calling a function with other arguments).
 * Raise it with NATIVE_VERSION in native.py whenever a function or its arguments change. */
int64_t prs3_native_version(void) { return 5; }

static const char PAIRS[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

/* the last (end - start) decimal digits of value into out[start:end] */
static inline __attribute__((always_inline)) void digits(uint64_t value, uint8_t *start, uint8_t *end) {
    uint8_t *at = end;
    while (at - 2 >= start) {
        uint64_t quotient = value / 100;
        unsigned pair = (unsigned)(value - quotient * 100) * 2;
        at[-2] = (uint8_t)PAIRS[pair];
        at[-1] = (uint8_t)PAIRS[pair + 1];
        at -= 2;
        value = quotient;
    }
    if (at > start) *start = (uint8_t)('0' + value % 10);
}

static int count_digits(uint64_t value) {
    int count = 1;
    while (value >= 10) {
        value /= 10;
        count++;
    }
    return count;
}

/* value / 10^d, d = 0 .. 19: a division by a constant is a multiplication (a division by a variable
 * is the slowest instruction in the line writer, one per number) */
static inline uint64_t divide_power(uint64_t value, int d) {
    switch (d) {
    case 0: return value;
    case 1: return value / 10ULL;
    case 2: return value / 100ULL;
    case 3: return value / 1000ULL;
    case 4: return value / 10000ULL;
    case 5: return value / 100000ULL;
    case 6: return value / 1000000ULL;
    case 7: return value / 10000000ULL;
    case 8: return value / 100000000ULL;
    case 9: return value / 1000000000ULL;
    case 10: return value / 10000000000ULL;
    case 11: return value / 100000000000ULL;
    case 12: return value / 1000000000000ULL;
    case 13: return value / 10000000000000ULL;
    case 14: return value / 100000000000000ULL;
    case 15: return value / 1000000000000000ULL;
    case 16: return value / 10000000000000000ULL;
    case 17: return value / 100000000000000000ULL;
    case 18: return value / 1000000000000000000ULL;
    default: return value / 10000000000000000000ULL;
    }
}

/* size bytes from from to to; the usual word prefixes and choices (1 to 3 bytes) without a call */
static inline uint8_t *copy(uint8_t *to, const uint8_t *from, int64_t size) {
    switch (size) {
    case 3: to[2] = from[2]; /* fall through */
    case 2: to[1] = from[1]; /* fall through */
    case 1: to[0] = from[0]; /* fall through */
    case 0: return to + size;
    default: memcpy(to, from, (size_t)size); return to + size;
    }
}

static const uint64_t POWERS[20] = {
    1ULL, 10ULL, 100ULL, 1000ULL, 10000ULL, 100000ULL, 1000000ULL, 10000000ULL, 100000000ULL,
    1000000000ULL, 10000000000ULL, 100000000000ULL, 1000000000000ULL, 10000000000000ULL,
    100000000000000ULL, 1000000000000000ULL, 10000000000000000ULL, 100000000000000000ULL,
    1000000000000000000ULL, 10000000000000000000ULL};

/* value (the printed digits without the point) with d digits after the point: at most 21 bytes, and
 * up to 3 bytes after those may be written over (the callers leave room for them). The usual numbers
 * (a whole part under 10,000) go without a branch on their digits: a mispredicted branch per word
 * was the line writer's largest cost. */
/* DIGITS4[k]: the four ASCII digits of k < 10,000 with leading zeros, as stored little-endian */
static uint32_t DIGITS4[10000];
__attribute__((constructor)) static void fill_digits4(void) {
    for (unsigned k = 0; k < 10000; k++) {
        uint8_t text[4] = {(uint8_t)('0' + k / 1000), (uint8_t)('0' + k / 100 % 10), (uint8_t)('0' + k / 10 % 10),
                           (uint8_t)('0' + k % 10)};
        memcpy(&DIGITS4[k], text, 4);
    }
}

static inline __attribute__((always_inline)) uint8_t *number(uint8_t *at, int64_t value, int d) {
    uint64_t magnitude = value < 0 ? (uint64_t)0 - (uint64_t)value : (uint64_t)value;
    *at = '-';
    at += value < 0;
    uint64_t whole = divide_power(magnitude, d);
    uint64_t fraction = magnitude - whole * POWERS[d];
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    if (whole < 10000) {
        /* the four digits with leading zeros in one word, shifted so that the first byte is the first digit */
        uint32_t four = DIGITS4[whole];
        int count = 1 + (whole >= 10) + (whole >= 100) + (whole >= 1000);
        four >>= 8 * (4 - count);
        memcpy(at, &four, 4);
        at += count;
    } else
#endif
    {
        int count = count_digits(whole);
        digits(whole, at, at + count);
        at += count;
    }
    if (d == 4) {                                 /* the usual decimals without a loop */
        *at = '.';
        memcpy(at + 1, &DIGITS4[fraction], 4);
        return at + 5;
    }
    if (d == 3) {
        unsigned high = (unsigned)fraction / 100, low = (unsigned)fraction % 100;
        *at = '.';
        at[1] = (uint8_t)('0' + high);
        memcpy(at + 2, PAIRS + 2 * low, 2);
        return at + 4;
    }
    if (d > 0) {
        *at++ = '.';
        digits(fraction, at, at + d);
        at += d;
    }
    return at;
}

/* What prs3_render_lines returns besides the bytes written (prs3_post.core.native names them too). */
enum { RENDER_OVERFLOW = -1, RENDER_BAD_COLUMN = -2 };
/* The most digits after the point a number column may have (POWERS, divide_power). */
enum { MAX_DECIMALS = 19 };

/* Returns the bytes written; RENDER_OVERFLOW when out (capacity bytes) would overflow;
 * RENDER_BAD_COLUMN where a column is neither kind, a number column's decimals are not 0 to
 * MAX_DECIMALS, or a choice is not one of its column's texts (nothing is promised about out then).
 * kind[c]: 0 a number (value = printed digits, decimals[c] after the point, text first_text[c] its
 * prefix), 1 a choice (value = k, text first_text[c] + k, k < first_text[c + 1] - first_text[c]):
 * first_text has columns + 1 entries, the last the count of texts. Text t is
 * text_bytes[text_start[t]:text_start[t + 1]]. present is (rows, columns) bytes, row-major.
 * lengths[r]: line r's length with its ending. */
int64_t prs3_render_lines(int64_t columns, int64_t rows, const int64_t *const *values, const int32_t *kind,
                          const int32_t *decimals, const int64_t *first_text, const int64_t *text_start,
                          const uint8_t *text_bytes, const uint8_t *present, uint8_t separator,
                          const uint8_t *ending, int64_t ending_length, int64_t overrides,
                          const int64_t *override_row, const int64_t *override_col,
                          const int64_t *override_start, const uint8_t *override_bytes, uint8_t *out,
                          int64_t capacity, int64_t *lengths) {
    for (int64_t c = 0; c < columns; c++) {
        if (kind[c] == 0 ? decimals[c] < 0 || decimals[c] > MAX_DECIMALS : kind[c] != 1) return RENDER_BAD_COLUMN;
        if (first_text[c + 1] < first_text[c] + 1) return RENDER_BAD_COLUMN;   /* a number: its prefix */
    }
    uint8_t *at = out;
    uint8_t *const limit = out + capacity;
    int64_t next = 0;
    for (int64_t r = 0; r < rows; r++) {
        uint8_t *const line = at;
        int first = 1;
        const uint8_t *on = present + r * columns;
        for (int64_t c = 0; c < columns; c++) {
            int overridden = next < overrides && override_row[next] == r && override_col[next] == c;
            if (!on[c]) {
                next += overridden;
                continue;
            }
            /* the longest word: separator, text, sign, 20 digits, point, 19 decimals */
            if (limit - at < 64 + (text_start[first_text[c] + 1] - text_start[first_text[c]])) return RENDER_OVERFLOW;
            if (!first) *at++ = separator;
            first = 0;
            int64_t value = values[c][r];
            if (kind[c] == 1) {
                if (value < 0 || value >= first_text[c + 1] - first_text[c]) return RENDER_BAD_COLUMN;
                int64_t t = first_text[c] + value;
                int64_t size = text_start[t + 1] - text_start[t];
                if (limit - at < size) return RENDER_OVERFLOW;
                at = copy(at, text_bytes + text_start[t], size);
                continue;
            }
            int64_t t = first_text[c];
            at = copy(at, text_bytes + text_start[t], text_start[t + 1] - text_start[t]);
            if (overridden) {
                int64_t size = override_start[next + 1] - override_start[next];
                if (limit - at < size) return RENDER_OVERFLOW;
                memcpy(at, override_bytes + override_start[next], (size_t)size);
                at += size;
                next++;
                continue;
            }
            at = number(at, value, decimals[c]);
        }
        if (limit - at < ending_length) return RENDER_OVERFLOW;
        memcpy(at, ending, (size_t)ending_length);
        at += ending_length;
        lengths[r] = at - line;
    }
    return at - out;
}

/* |value·10^d| at or above 2^52 (and nan, inf) is not written from integers (prs3_post.fixed._EXACT_LIMIT). */
static const double EXACT_LIMIT = 4503599627370496.0;
static const double SCALES[16] = {1e0, 1e1, 1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                  1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15};
enum { MAX_AXES = 8 };

/* numpy's rint(y) for |y| < 2^52 (round to nearest, ties to even) without a libm call: y ± 2^52 has
 * no bits after the point, so that addition rounds y exactly as rint does (the compiler does not
 * reassociate floating point without -ffast-math, which csrc is never built with). */
static inline double nearest_integer(double y) {
    double shift = copysign(EXACT_LIMIT, y);      /* no branch on the sign */
    return (y + shift) - shift;
}

/* The bytes a motion line needs at most (checked before each row; prs3_post.native.emit_rows gives out
 * this much a row): every text (the prefixes, G0 and G1, F, the block number's letter), and for each
 * number a separator, a sign, 19 digits and a point (ROOM_PER_NUMBER), and the ending. */
enum { ROOM_PER_NUMBER = 24 };
static int64_t row_room(int64_t axes, const int64_t *text_start, int64_t ending_length) {
    return text_start[axes + 4] + ROOM_PER_NUMBER * (axes + 2) + ending_length;
}

/* The motion lines of rows of a program (prs3_post.emit.gcode.ProgramEmitter), scaled, decided and
 * written in one pass; the numpy way (scale_column, _words_present, render_rows) makes the same bytes.
 *
 * Axis j's value on row r is axis_values[j][r * axis_stride[j]], printed with `decimals` digits after
 * the point as the integer rint(value·10^decimals) (prs3_post.fixed.scale_column). An axis word is
 * written where that integer differs from the row before's, on row 0 where first_present[j], and on
 * every row of restate_row[] (increasing). The motion word (texts axes: G0 for kind 0, axes + 1: G1
 * for kind 1) is written on every line, or with modal_motion only where the kind differs from the
 * row before's (previous_kind for row 0, -1: unknown), on a restate row, or on a line without axis
 * word. F (text axes + 2) and its value, axis_values[axes][r * axis_stride[axes]] scaled the same way
 * with feed_decimals, go on kind-1 rows. Where numbers is not
 * NULL, each line starts with its block number: text axes + 3 (N) and numbers[r]. Text t is
 * text_bytes[text_start[t]:text_start[t + 1]] (t < axes: the axis letters). Before row r come the
 * lines insert_bytes[insert_start[i]:insert_start[i + 1]] of each i with insert_row[i] == r
 * (increasing, < rows). starts[r]: where row r's inserted lines (then its line) begin, starts[rows]
 * the end; lengths[r]: row r's line with its ending.
 *
 * Returns the bytes written; -1 when out (capacity bytes) would overflow; -2 - r where a value of
 * row r cannot be printed from an exact integer (|value·10^d| >= 2^52, not finite, or within 2^-40
 * plus |value·10^d|·2^-49 of a half-integer: a superset of the rows scale_column formats one by one
 * with Python): nothing is promised about out then, the caller writes these rows the numpy way. */
int64_t prs3_emit_lines(int64_t rows, int64_t axes, const double *const *axis_values, const int64_t *axis_stride,
                        int32_t decimals, const uint8_t *first_present, const int64_t *kind, int64_t previous_kind,
                        int64_t restates, const int64_t *restate_row, int32_t modal_motion,
                        int32_t feed_decimals, const int64_t *numbers, const int64_t *text_start,
                        const uint8_t *text_bytes, uint8_t separator, const uint8_t *ending, int64_t ending_length,
                        int64_t inserts, const int64_t *insert_row, const int64_t *insert_start,
                        const uint8_t *insert_bytes, uint8_t *out, int64_t capacity, int64_t *starts,
                        int64_t *lengths) {
    if (axes < 0 || axes > MAX_AXES || decimals < 0 || decimals > 15 || feed_decimals < 0 || feed_decimals > 15)
        return -1;
    const double scale = SCALES[decimals], feed_scale = SCALES[feed_decimals];
    const double *const feed = axis_values[axes];
    const int64_t feed_stride = axis_stride[axes];
    const int64_t room = row_room(axes, text_start, ending_length);
    uint8_t *at = out;
    uint8_t *const limit = out + capacity;
    int64_t last[MAX_AXES] = {0}, scaled[MAX_AXES];
    int on[MAX_AXES];
    int64_t next_restate = 0, next_insert = 0, previous = previous_kind;
    for (int64_t r = 0; r < rows; r++) {
        starts[r] = at - out;
        while (next_insert < inserts && insert_row[next_insert] == r) {
            int64_t size = insert_start[next_insert + 1] - insert_start[next_insert];
            if (limit - at < size) return -1;
            memcpy(at, insert_bytes + insert_start[next_insert], (size_t)size);
            at += size;
            next_insert++;
        }
        int restate = next_restate < restates && restate_row[next_restate] == r;
        next_restate += restate;
        int any = 0;
        for (int64_t j = 0; j < axes; j++) {
            double y = axis_values[j][r * axis_stride[j]] * scale;      /* as numpy: one rounding */
            double size = fabs(y);
            if (!(size < EXACT_LIMIT)) return -2 - r;
            double whole = nearest_integer(y);
            if (fabs(y - whole) >= 0.5 - (size * 0x1p-49 + 0x1p-40)) return -2 - r;   /* near a tie */
            scaled[j] = (int64_t)whole;
            on[j] = restate || (r == 0 ? first_present[j] != 0 : scaled[j] != last[j]);
            any |= on[j];
            last[j] = scaled[j];
        }
        int64_t k = kind[r];
        int motion = !modal_motion || restate || k != previous || !any;
        previous = k;
        if (limit - at < room) return -1;
        uint8_t *const line = at;
        int first = 1;
        if (numbers) {
            at = copy(at, text_bytes + text_start[axes + 3], text_start[axes + 4] - text_start[axes + 3]);
            at = number(at, numbers[r], 0);
            first = 0;
        }
        if (motion) {
            int64_t t = axes + (k == 1);
            if (!first) *at++ = separator;
            at = copy(at, text_bytes + text_start[t], text_start[t + 1] - text_start[t]);
            first = 0;
        }
        for (int64_t j = 0; j < axes; j++) {
            if (!on[j]) continue;
            if (!first) *at++ = separator;
            first = 0;
            at = copy(at, text_bytes + text_start[j], text_start[j + 1] - text_start[j]);
            at = number(at, scaled[j], decimals);
        }
        if (k == 1) {
            double y = feed[r * feed_stride] * feed_scale;
            double size = fabs(y);
            if (!(size < EXACT_LIMIT)) return -2 - r;
            double whole = nearest_integer(y);
            if (fabs(y - whole) >= 0.5 - (size * 0x1p-49 + 0x1p-40)) return -2 - r;       /* near a tie */
            if (!first) *at++ = separator;
            at = copy(at, text_bytes + text_start[axes + 2], text_start[axes + 3] - text_start[axes + 2]);
            at = number(at, (int64_t)whole, feed_decimals);
        }
        memcpy(at, ending, (size_t)ending_length);
        at += ending_length;
        lengths[r] = at - line;
    }
    starts[rows] = at - out;
    return at - out;
}
