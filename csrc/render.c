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
#include <stdint.h>
#include <string.h>

/* The version of the library's functions and their arguments: prs3_post/native.py loads a library
 * only when it says the version that module was written for (an editable install whose csrc/ changed
 * since it was built falls back to numpy instead of calling a function with other arguments).
 * Raise it with NATIVE_VERSION in native.py whenever a function or its arguments change. */
int64_t prs3_native_version(void) { return 2; }

static const char PAIRS[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

/* the last (end - start) decimal digits of value into out[start:end] */
static void digits(uint64_t value, uint8_t *start, uint8_t *end) {
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

/* Returns the bytes written, or -1 when out (capacity bytes) would overflow (nothing is promised
 * about out then). kind[c]: 0 a number (value = printed digits, decimals[c] after the point, text
 * first_text[c] its prefix), 1 a choice (value = k, text first_text[c] + k). Text t is
 * text_bytes[text_start[t]:text_start[t + 1]]. present is (rows, columns) bytes, row-major.
 * lengths[r]: line r's length with its ending. */
int64_t prs3_render_lines(int64_t columns, int64_t rows, const int64_t *const *values, const int32_t *kind,
                          const int32_t *decimals, const int64_t *first_text, const int64_t *text_start,
                          const uint8_t *text_bytes, const uint8_t *present, uint8_t separator,
                          const uint8_t *ending, int64_t ending_length, int64_t overrides,
                          const int64_t *override_row, const int64_t *override_col,
                          const int64_t *override_start, const uint8_t *override_bytes, uint8_t *out,
                          int64_t capacity, int64_t *lengths) {
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
            if (limit - at < 64 + (text_start[first_text[c] + 1] - text_start[first_text[c]])) return -1;
            if (!first) *at++ = separator;
            first = 0;
            int64_t value = values[c][r];
            if (kind[c] == 1) {
                int64_t t = first_text[c] + value;
                int64_t size = text_start[t + 1] - text_start[t];
                if (limit - at < size) return -1;
                at = copy(at, text_bytes + text_start[t], size);
                continue;
            }
            int64_t t = first_text[c];
            at = copy(at, text_bytes + text_start[t], text_start[t + 1] - text_start[t]);
            if (overridden) {
                int64_t size = override_start[next + 1] - override_start[next];
                if (limit - at < size) return -1;
                memcpy(at, override_bytes + override_start[next], (size_t)size);
                at += size;
                next++;
                continue;
            }
            uint64_t magnitude;
            if (value < 0) {
                *at++ = '-';
                magnitude = (uint64_t)0 - (uint64_t)value;
            } else {
                magnitude = (uint64_t)value;
            }
            int d = decimals[c];
            uint64_t whole = divide_power(magnitude, d);
            uint64_t fraction = magnitude - whole * POWERS[d];
            int count = count_digits(whole);
            digits(whole, at, at + count);
            at += count;
            if (d > 0) {
                *at++ = '.';
                digits(fraction, at, at + d);
                at += d;
            }
        }
        if (limit - at < ending_length) return -1;
        memcpy(at, ending, (size_t)ending_length);
        at += ending_length;
        lengths[r] = at - line;
    }
    return at - out;
}
