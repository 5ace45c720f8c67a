// locus/ids.hpp: the one id rule (config device ids and instance names, scene ids, link messages).
#include "locus/ids.hpp"

#include <gtest/gtest.h>

#include <string>

namespace locus {
namespace {

TEST(Ids, LettersDigitsUnderscoreAndDashUpTo31Characters) {
  EXPECT_TRUE(valid_id("A"));
  EXPECT_TRUE(valid_id("phone_2-left"));
  EXPECT_TRUE(valid_id(std::string(31, 'x')));
  EXPECT_EQ(kMaxIdLength, 31u);
  EXPECT_EQ(id_problem(""), IdProblem::Empty);
  EXPECT_EQ(id_problem("a b"), IdProblem::BadCharacter);
  EXPECT_EQ(id_problem("a.b"), IdProblem::BadCharacter);
  EXPECT_EQ(id_problem("*"), IdProblem::BadCharacter);
  EXPECT_EQ(id_problem("\xc3\xa9t\xc3\xa9"), IdProblem::BadCharacter);  // UTF-8 is not an id
  EXPECT_EQ(id_problem(std::string(32, 'x')), IdProblem::TooLong);
  EXPECT_FALSE(valid_id(std::string(32, 'x')));
}

TEST(Ids, CharactersAreJudgedBeforeTheLength) {
  EXPECT_EQ(id_problem(std::string(40, ' ')), IdProblem::BadCharacter);
}

TEST(Ids, UsableAtCompileTime) {
  static_assert(valid_id("A"));
  static_assert(!valid_id(""));
  static_assert(is_id_char('-') && !is_id_char('/'));
}

}  // namespace
}  // namespace locus
