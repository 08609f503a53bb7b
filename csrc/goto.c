/* The CL reader's bulk GOTO path (prs3_post.readers.apt._plain_goto_text), in C (loaded with ctypes
 * by prs3_post.native).
 *
 * Reads the plain GOTO lines of a chunk (`GOTO/x,y,z` or `GOTO/x,y,z,i,j,k`, apt._PLAIN_GOTO, numbers
 * of at most MAX_DIGITS digits) with the same rules as the numpy path (a test compares the two on
 * generated chunks): the line starts with "GOTO/"; every byte is allowed after the one before it (the
 * table of bad code pairs the caller passes, apt._GOTO_PAIR_BAD, made from apt._GOTO_AFTER: one
 * definition of the rules); a number is what follows "/" or "," up to the next ",", CR or line end:
 * an optional sign, digits with at most one point, a digit beside the point (decimal.h); 3 or 6
 * numbers. A line that breaks a rule is not read: its row is all NaN and the Python reader reads it
 * (or says what is wrong).
 *
 * Plain C with no Python API: ctypes releases the GIL for the call (convert reads the next chunk on a
 * second thread, read_ahead). No state outside the call: two threads may read at once.
 *
 * prs3_native_version() (render.c) covers this function too: raise it (and NATIVE_VERSION in
 * native.py) when its arguments change.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "decimal.h"

/* the byte codes of the caller's table (apt._GC_*) */
enum { OTHER, DIGIT, SIGN, PREFIX, DOT, COMMA, SLASH, CR, NEWLINE };
enum { COLUMNS = 6 };                                  /* x, y, z, i, j, k */

static void fill_nan(double *row) {
    for (int c = 0; c < COLUMNS; c++) row[c] = NAN;
}

/* text[0:size]: a LF, then lines each ending in LF. codes: 256 bytes, each byte's code (apt._GC_*);
 * pair_bad: 256 bytes, 1 where a byte of code `this` may not follow one of code `before`, at
 * (before << 4) | this (codes below 16).
 * Writes, for the N lines: values (N, 6) row-major, x y z i j k of each line read (NaN for no i j k)
 * and NaN on every line not read; read[k] 1 where line k is read.
 * Returns N, or -1 (nothing promised about the outputs) when the text does not start and end with a
 * LF or N > rows (values and read have room for `rows` lines). */
int64_t prs3_plain_gotos(const uint8_t *text, int64_t size, const uint8_t *codes, const uint8_t *pair_bad,
                         double *values, uint8_t *read, int64_t rows) {
    if (size < 1 || text[0] != '\n' || text[size - 1] != '\n' || rows < 0) return -1;
    int64_t n = 0;
    int64_t pos = 1;
    while (pos < size) {                                /* one line: text[pos] up to its LF */
        if (n >= rows) return -1;
        double *row = values + n * COLUMNS;
        fill_nan(row);
        int bad = size - pos < 6 || memcmp(text + pos, "GOTO/", 5) != 0;   /* (6: with its LF) */
        if (!bad) {
            pos += 5;                                   /* "GOTO/": every pair allowed */
            int before = SLASH;
            int count = 0;                              /* numbers ended so far */
            int inside = 1;                             /* in a number (after "/" or ",") */
            struct decimal number = DECIMAL_START;
            for (;; pos++) {
                uint8_t byte = text[pos];
                int code = codes[byte];
                if (code > NEWLINE || pair_bad[before << 4 | code]) {
                    bad = 1;
                    break;
                }
                before = code;
                if (code == DIGIT) {
                    if (!decimal_digit(&number, byte)) {
                        bad = 1;
                        break;
                    }
                } else if (code == DOT) {
                    if (!decimal_point(&number)) {      /* a second point */
                        bad = 1;
                        break;
                    }
                } else if (code == SIGN) {              /* only right after "/" or "," (pair_bad) */
                    number.minus = byte == '-';
                } else if (code == COMMA || code == CR || code == NEWLINE) {
                    if (inside) {                       /* the number ends */
                        if (number.digits == 0 || count == COLUMNS) {   /* a lonely point; a 7th number */
                            bad = 1;
                            break;
                        }
                        row[count++] = decimal_value(&number);
                        number = DECIMAL_START;
                        inside = code == COMMA;
                    }
                    if (code == NEWLINE) break;
                } else {                                /* a letter of GOTO, "/", other: not allowed here */
                    bad = 1;
                    break;
                }
            }
            if (!bad && count != 3 && count != COLUMNS) bad = 1;
        }
        if (bad) {
            fill_nan(row);
            const uint8_t *end = memchr(text + pos, '\n', (size_t)(size - pos));
            pos = end - text;                           /* found: the text ends with a LF */
        }
        read[n++] = (uint8_t)!bad;
        pos++;
    }
    return n;
}
