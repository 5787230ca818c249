#include "lodforge/batch/glob.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace lodforge::batch {
namespace {

TEST(Glob, StarStaysInsideOneSegment) {
  EXPECT_TRUE(glob_match("*.obj", "chair.obj"));
  EXPECT_FALSE(glob_match("*.obj", "props/chair.obj"));
  EXPECT_TRUE(glob_match("props/*.obj", "props/chair.obj"));
  EXPECT_FALSE(glob_match("props/*.obj", "props/kitchen/chair.obj"));
  EXPECT_TRUE(glob_match("props/*", "props/.hidden"));
  EXPECT_TRUE(glob_match("*chair*", "chair"));
  EXPECT_FALSE(glob_match("*.obj", "chair.obj.bak"));
}

TEST(Glob, WholePathMustMatch) {
  EXPECT_TRUE(glob_match("props/chair.obj", "props/chair.obj"));
  EXPECT_FALSE(glob_match("props/chair.obj", "props/chair.objx"));
  EXPECT_FALSE(glob_match("props", "props/chair.obj"));
  EXPECT_FALSE(glob_match("props/chair.obj", "Props/chair.obj"));  // case-sensitive
}

TEST(Glob, StarBacktracks) {
  EXPECT_TRUE(glob_match("*a*a*b", "xaxaxaab"));
  EXPECT_FALSE(glob_match("*a*a*b", "xaxaxaa"));
  EXPECT_TRUE(glob_match("a*b*c", "abbbcbc"));
  EXPECT_TRUE(glob_match("*_LOD*.glb", "tree_LOD_LOD2.glb"));
}

TEST(Glob, QuestionMarkIsOneCharacterNotSlash) {
  EXPECT_TRUE(glob_match("rock?.ply", "rock1.ply"));
  EXPECT_FALSE(glob_match("rock?.ply", "rock12.ply"));
  EXPECT_FALSE(glob_match("rock?.ply", "rock.ply"));
  EXPECT_FALSE(glob_match("a?b", "a/b"));
  EXPECT_TRUE(glob_match("caf?.obj", "caf\xC3\xA9.obj"));  // one UTF-8 code point, two bytes
}

TEST(Glob, DoubleStarMatchesZeroOrMoreSegments) {
  EXPECT_TRUE(glob_match("**/*.obj", "chair.obj"));
  EXPECT_TRUE(glob_match("**/*.obj", "props/chair.obj"));
  EXPECT_TRUE(glob_match("**/*.obj", "a/b/c/chair.obj"));
  EXPECT_FALSE(glob_match("**/*.obj", "a/b/c/chair.ply"));
  EXPECT_TRUE(glob_match("props/**", "props/chair.obj"));
  EXPECT_TRUE(glob_match("props/**", "props/kitchen/chair.obj"));
  EXPECT_FALSE(glob_match("props/**", "environment/rock.ply"));
  EXPECT_TRUE(glob_match("props/**/chair.obj", "props/chair.obj"));
  EXPECT_TRUE(glob_match("props/**/chair.obj", "props/a/b/chair.obj"));
  EXPECT_FALSE(glob_match("props/**/chair.obj", "props/a/b/table.obj"));
  EXPECT_TRUE(glob_match("**/props/**", "props/chair.obj"));
  EXPECT_TRUE(glob_match("**/props/**", "level1/props/big/chair.obj"));
  EXPECT_FALSE(glob_match("**/props/**", "level1/propsx/chair.obj"));
  EXPECT_TRUE(glob_match("**", "anything/at/all"));
  EXPECT_TRUE(glob_match("**/*", "x"));
  EXPECT_TRUE(glob_match("a/**/b/**/c", "a/x/b/y/z/c"));
  EXPECT_FALSE(glob_match("a/**/b/**/c", "a/x/y/z/c"));
}

TEST(Glob, CharacterClasses) {
  EXPECT_TRUE(glob_match("lod[123].obj", "lod2.obj"));
  EXPECT_FALSE(glob_match("lod[123].obj", "lod4.obj"));
  EXPECT_TRUE(glob_match("[a-c]*.obj", "bench.obj"));
  EXPECT_FALSE(glob_match("[a-c]*.obj", "desk.obj"));
  EXPECT_TRUE(glob_match("[!a-c]*.obj", "desk.obj"));
  EXPECT_TRUE(glob_match("[^a-c]*.obj", "desk.obj"));
  EXPECT_FALSE(glob_match("[!a-c]*.obj", "bench.obj"));
  EXPECT_TRUE(glob_match("[]]x", "]x"));
  EXPECT_TRUE(glob_match("[a-]", "-"));
  EXPECT_TRUE(glob_match("[\xC3\xA9]", "\xC3\xA9"));
  EXPECT_FALSE(glob_match("[!x]", "a/"));
}

TEST(Glob, BracesExpandIncludingAcrossSegmentsAndNested) {
  EXPECT_TRUE(glob_match("props/*.{obj,stl}", "props/chair.obj"));
  EXPECT_TRUE(glob_match("props/*.{obj,stl}", "props/bracket.stl"));
  EXPECT_FALSE(glob_match("props/*.{obj,stl}", "props/rock.ply"));
  EXPECT_TRUE(glob_match("{props,environment}/**", "environment/rock.ply"));
  EXPECT_TRUE(glob_match("{a/b,c}/x", "a/b/x"));
  EXPECT_TRUE(glob_match("{a/b,c}/x", "c/x"));
  EXPECT_TRUE(glob_match("x{,_hi}.obj", "x.obj"));
  EXPECT_TRUE(glob_match("x{,_hi}.obj", "x_hi.obj"));
  EXPECT_TRUE(glob_match("{a,{b,c}d}", "cd"));
  EXPECT_FALSE(glob_match("{a,{b,c}d}", "c"));
  EXPECT_TRUE(glob_match("{**/,}tree.gltf", "tree.gltf"));
  EXPECT_TRUE(glob_match("a,b", "a,b"));  // commas outside braces are literal
  EXPECT_TRUE(glob_match("[{]x", "{x"));  // braces inside a class are literal
}

TEST(Glob, EscapesMakeCharactersLiteral) {
  EXPECT_TRUE(glob_match("a\\*b", "a*b"));
  EXPECT_FALSE(glob_match("a\\*b", "axb"));
  EXPECT_TRUE(glob_match("\\{a\\}", "{a}"));
  EXPECT_TRUE(glob_match("\\[x]", "[x]"));
}

TEST(Glob, KeepsPatternText) {
  EXPECT_EQ(Glob::compile("props/**").pattern(), "props/**");
}

void expect_problem(const std::string& pattern, const std::string& problem) {
  EXPECT_EQ(Glob::problem(pattern), problem) << pattern;
  try {
    Glob::compile(pattern);
    ADD_FAILURE() << pattern << " compiled";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(e.what(), problem);
  }
}

TEST(Glob, ReportsMalformedPatterns) {
  expect_problem("", "empty pattern");
  expect_problem("{,}", "empty pattern");
  expect_problem("/props/*", "must be relative (starts with '/')");
  expect_problem("props//x", "empty path segment ('//')");
  expect_problem("props/", "ends with '/'");
  expect_problem("props/[ab", "unclosed '['");
  expect_problem("[]", "unclosed '['");
  expect_problem("props/{a,b", "unclosed '{'");
  expect_problem("props/a}", "unmatched '}'");
  expect_problem("a**", "'**' must be a whole path segment (\"**/x\", \"a/**\")");
  expect_problem("**a/b", "'**' must be a whole path segment (\"**/x\", \"a/**\")");
  expect_problem("***/b", "'**' must be a whole path segment (\"**/x\", \"a/**\")");
  expect_problem("a/../b", "'.' and '..' segments are not allowed");
  expect_problem("./b", "'.' and '..' segments are not allowed");
  expect_problem("[a/b]", "'/' cannot appear inside '[...]'");
  expect_problem("[z-a]", "reversed range in '[...]'");
  expect_problem("ab\\", "trailing '\\'");
  expect_problem("{a,b}{a,b}{a,b}{a,b}{a,b}{a,b}{a,b}{a,b}{a,b}", "'{...}' expands to more than 256 alternatives");
  EXPECT_EQ(Glob::problem("props/**/*.{obj,stl}"), "");
}

TEST(Glob, CopiesShareTheCompiledPattern) {
  const Glob a = Glob::compile("**/*.obj");
  const Glob b = a;  // NOLINT(performance-unnecessary-copy-initialization): the copy is what is tested
  EXPECT_TRUE(b.matches("x/y.obj"));
  EXPECT_EQ(b.pattern(), a.pattern());
}

}  // namespace
}  // namespace lodforge::batch
