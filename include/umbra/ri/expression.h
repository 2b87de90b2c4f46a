#pragma once
// Conditional RIB (RenderMan 13+): the expressions of `IfBegin` and
// `ElseIf`, e.g. "$user:pass == 'shadow' && $Frame > 1".
//
//   or      := and ( '||' and )*
//   and     := not ( '&&' not )*
//   not     := '!' not | compare
//   compare := sum ( ( '==' | '!=' | '<' | '>' | '<=' | '>=' | '=~' ) sum )?
//   sum     := product ( ( '+' | '-' ) product )*
//   product := unary ( ( '*' | '/' ) unary )*
//   unary   := ( '-' | '+' ) unary | primary
//   primary := number | 'string' | "string" | reference | 'defined' '(' reference ')'
//            | 'concat' '(' or ( ',' or )* ')' | 'true' | 'false' | '(' or ')'
//   reference := '$' name | '${' name '}' | '$(' name ')' | '$(' or ')'
//                (name: letters, digits, _ : .; the last form names what
//                its expression's value spells)
//
// Two numbers compare as numbers, anything else as text. Arithmetic takes
// numbers and strings that spell one. `a =~ b` is true when the
// ECMAScript regular expression b matches somewhere in the text of a. In
// a quoted string a backslash escapes the quote or a backslash. A value
// is true when it is a non-zero number or a non-empty string. (Pixie's
// grammar, with PRMan's =~.)

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace umbra::ri {

/// A value in a condition: a number or a string.
struct ExprValue {
    bool isString = false;
    double num = 0;
    std::string str;
};

/// Resolves a reference (the name after '$', e.g. "user:pass"); false when
/// it names nothing.
using ExprLookup = std::function<bool(const std::string& name, ExprValue* out)>;

/// Evaluates `expr`. False with `*error` set when it is malformed. A
/// reference that names nothing is the empty string; its name is added to
/// `*undefined` (once) so the caller can warn.
bool evaluateCondition(std::string_view expr, const ExprLookup& lookup, bool* result, std::string* error,
                       std::vector<std::string>* undefined);

}  // namespace umbra::ri
