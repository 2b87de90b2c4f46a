#pragma once
// Conditional RIB (RenderMan 13+): the expressions of `IfBegin` and
// `ElseIf`, e.g. "$user:pass == 'shadow' && $Frame > 1".
//
//   or      := and ( '||' and )*
//   and     := not ( '&&' not )*
//   not     := '!' not | compare
//   compare := primary ( ( '==' | '!=' | '<' | '>' | '<=' | '>=' ) primary )?
//   primary := number | 'string' | "string" | reference | 'defined' '(' reference ')'
//            | 'true' | 'false' | '(' or ')'
//   reference := '$' name | '${' name '}'     (name: letters, digits, _ : .)
//
// Two numbers compare as numbers, anything else as text. A value is true
// when it is a non-zero number or a non-empty string.

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
