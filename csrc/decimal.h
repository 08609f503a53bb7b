/* How the compiled readers (lex.c, goto.c) read a plain decimal number: one definition.
 *
 * A number is digits with at most one point among them, read one byte at a time (decimal_digit,
 * decimal_point) after its sign. The digits (at most MAX_DIGITS) make an exact integer (< 10^15 <
 * 2^53), then ONE correctly rounded division by 10^d (d digits after the point), or by -10^d for a
 * minus (so "-0" is -0.0); 10^d (d <= 15) is exact as a double. So decimal_value is Python's float()
 * of the text to the bit, as prs3_post.readers.lexer.decimal_numbers makes it with numpy.
 */
#ifndef PRS3_DECIMAL_H
#define PRS3_DECIMAL_H

#include <stdint.h>

/* A number of more digits is not read in bulk (its line goes to the Python reader). */
enum { MAX_DIGITS = 15 };

static const double POWERS[MAX_DIGITS + 1] = {1e0, 1e1, 1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                              1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15};

/* A number being read: start each with DECIMAL_START. */
struct decimal {
    uint64_t integer;                                   /* the digits so far, without the point */
    int digits, decimals, points, minus;                /* decimals: digits after the point */
};
#define DECIMAL_START ((struct decimal){0, 0, 0, 0, 0})

/* The next digit ('0' to '9'); 0 where that makes more than MAX_DIGITS (the number is not read). */
static inline int decimal_digit(struct decimal *number, uint8_t byte) {
    number->integer = number->integer * 10 + (uint64_t)(byte - '0');
    number->decimals += number->points;
    return ++number->digits <= MAX_DIGITS;
}

/* A point; 0 where it is the second (the number is not read). */
static inline int decimal_point(struct decimal *number) { return ++number->points == 1; }

/* The number's value (at least one digit read: a lonely point is the caller's to refuse). */
static inline double decimal_value(const struct decimal *number) {
    double power = POWERS[number->decimals];
    return (double)(int64_t)number->integer / (number->minus ? -power : power);
}

#endif
